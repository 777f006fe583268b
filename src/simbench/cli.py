"""Command line: `simbench run | export | sweep | validate | list | inspect | compare | reproduce | bench | train-fk`.

Exit codes: 0 done as the scenario expects; 3 done, but the run broke a promise (status `limits`); 2 bad input
(a file system refusal before the run included); 1 the run failed (a full disk while writing included) or a bug
(SIMBENCH_DEBUG=1 for the traceback); 130 interrupted; 141 the output's reader went away (`| head`), silently.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import signal
import sys
from pathlib import Path
from typing import NoReturn

from simbench.commands.bench import command as bench_command
from simbench.core import interrupts
from simbench.core.errors import (NO_SPACE, OutputError, PhysicsError, RunError, ScenarioError, described,
                                  os_error_line, printable)
from simbench.core.resources import scenarios_dir, sweeps_dir
from simbench.outputs.plot_formats import FORMATS, TIMESERIES_FORMATS


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="simbench", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="plan, simulate, analyse and write a scenario's outputs")
    run.add_argument("scenario", type=Path)
    run.add_argument("--out", type=Path, default=None, help="output folder (default renders/<name>/)")
    run.add_argument("--no-video", action="store_true", help="skip the MP4")
    run.add_argument("--force", action="store_true", help="replace the output folder if it exists")
    run.add_argument("--quiet", action="store_true", help="print nothing but errors")
    run.add_argument("--plot-format", choices=FORMATS, default="png", help="the plots' file format (default png)")
    run.add_argument("--timeseries", choices=TIMESERIES_FORMATS, default=None,
                     help="also write the timeseries as timeseries.csv (as `simbench export` does)")
    _allow_code(run)
    export = sub.add_parser("export", help="write a run's timeseries.npz as timeseries.csv beside it: a row a sample, "
                                           "a column a joint's or an axis's, units in the header")
    export.add_argument("run_folder", type=Path, help="a run's output folder (renders/<name>/)")
    export.add_argument("--format", choices=TIMESERIES_FORMATS, default="csv", help="the file's format (default csv)")
    sweep = sub.add_parser("sweep", help="run a scenario over parameter grids or random samples, into one table")
    sweep.add_argument("sweep", type=Path)
    sweep.add_argument("--out", type=Path, default=None, help="output folder (default renders/sweeps/<name>/)")
    sweep.add_argument("--workers", type=int, default=None, help="runs at once (default: one per CPU)")
    sweep.add_argument("--ray", metavar="ADDRESS", default=None,
                       help="run on a Ray cluster: 'local' starts one here, or a running cluster's HOST:PORT or "
                            "ray://HOST:PORT (refused if it does not answer within 5 s)")
    sweep.add_argument("--force", action="store_true",
                       help="start over: replace whatever the output folder holds (default: resume)")
    sweep.add_argument("--dry-run", action="store_true", help="check the sweep and list its runs; run nothing")
    sweep.add_argument("--quiet", action="store_true", help="print nothing but errors")
    _allow_code(sweep)
    bench_command.add_parser(sub)
    validate = sub.add_parser("validate", help="check scenarios and their plans without simulating")
    validate.add_argument("scenarios", type=Path, nargs="+")
    validate.add_argument("--no-plan", action="store_true", help="check the files only: do not plan")
    sub.add_parser("list", help="list robots, planners, controllers, policies, metrics and shipped scenarios")
    inspect = sub.add_parser("inspect", help="print the arm simbench derives from an MJCF or URDF model, a robot "
                                             "file or a scenario's robot mapping, and where its tool is")
    inspect.add_argument("model", type=Path, help="an MJCF (.xml), a URDF, a robot file or a scenario (.yaml)")
    inspect.add_argument("--at", metavar="Q1,Q2,...", default=None,
                         help="pose the tool at these joint values, one per joint, as a task's start takes them: in "
                              "the file's units (a robot file's or scenario's units:; rad and m for a bare model) "
                              "unless --units says (default: a scenario's task.start, else the model's qpos0)")
    inspect.add_argument("--units", metavar="UNITS", default=None,
                         help="the units of --at and of the joint values shown: rad or deg, m or mm, or both "
                              "(e.g. deg or deg,mm)")
    inspect.add_argument("--json", action="store_true",
                         help="print the joints and the tool's pose as JSON, SI, in full precision")
    reproduce = sub.add_parser("reproduce", help="regenerate a paper's published results beside simbench's")
    reproduce.add_argument("paper", choices=["000", "001", "002", "003", "all"])
    reproduce.add_argument("--out", type=Path, default=Path("renders") / "reproduce",
                           help="output folder, one subfolder a paper (default renders/reproduce/)")
    reproduce.add_argument("--force", action="store_true", help="replace an earlier reproduction")
    compare = sub.add_parser("compare", help="run one scenario's task with several planners, cartesian_path "
                                             "methods or controllers")
    compare.add_argument("scenario", type=Path)
    which = compare.add_mutually_exclusive_group(required=True)
    which.add_argument("--planners", type=_names, default=None, help="comma-separated, e.g. "
                                                                    "decoupled_path,mink_baseline")
    which.add_argument("--methods", type=_names, default=None,
                       help="a cartesian_path scenario's task.method, comma-separated, e.g. pinv,dls_adaptive")
    compare.add_argument("--controllers", type=_names, default=None,
                         help="comma-separated (default: the scenario's own)")
    compare.add_argument("--out", type=Path, default=None, help="output folder (default renders/compare/<name>/)")
    compare.add_argument("--force", action="store_true", help="replace an earlier comparison")
    compare.add_argument("--quiet", action="store_true", help="no progress")
    compare.add_argument("--plot-format", choices=FORMATS, default="png", help="the plots' file format (default png)")
    _allow_code(compare)
    train = sub.add_parser("train-fk", help="retrain the Agile Eye's learnt forward kinematics (needs scikit-learn)")
    train.add_argument("--samples", type=int, default=20000, help="poses per working mode (75 %% train)")
    train.add_argument("--hidden", type=int, nargs="+", default=[64, 64], help="hidden layer sizes")
    train.add_argument("--seed", type=int, default=0)
    train.add_argument("--out", type=Path, default=None, help="weights file (default: the shipped one)")
    return parser


def _allow_code(command: argparse.ArgumentParser) -> None:
    """The flag that lets a scenario's control.policy name a module: importing it runs its code, as the user."""
    command.add_argument("--allow-code", action="store_true",
                         help="let control.policy name a Python module (package.module:factory): simbench imports "
                              "it, which runs its code with your rights")


EXIT_LIMITS = 3


def _say(text: str, file=None) -> None:
    """Print `text` with control characters but line breaks escaped: text read from files cannot drive the tty."""
    print("\n".join(printable(line) for line in str(text).split("\n")), file=file or sys.stdout)


def _names(text: str) -> list[str]:
    """A comma-separated list of names."""
    return [name.strip() for name in text.split(",") if name.strip()]


def _summary(result) -> str:
    r = result.report
    tr = r["tracking"]
    lines = [f"{r['scenario']['name']}: {printable(r['robot'])} / {r['planner']} -> {result.out}"]
    if "orientation_max" in tr:  # the task is an orientation: its error first, in degrees
        lines.append(f"  orientation vs plan: RMS {math.degrees(tr['orientation_rms']):.3f} deg, max "
                     f"{math.degrees(tr['orientation_max']):.3f} deg")
    lines += [f"  tool vs planned path: RMS {tr['tool_rms'] * 1e3:.3f} mm, max {tr['tool_max'] * 1e3:.3f} mm; "
              f"lag RMS {tr['tool_lag_rms'] * 1e3:.3f} mm",
              f"  events: {len(r['singularity_events'])} singularity, {len(r['limit_events'])} limit; "
              f"MuJoCo warnings: {len(r['warnings'])}"]
    lines += [f"  plan warning: {printable(w)}" for w in r["plan"]["warnings"]]
    lines += _status_lines(r["status"], r["violations"], r.get("expected"))
    return "\n".join(lines)


def _status_lines(status: str, violations: list[dict], expected: dict | None) -> list[str]:
    """The status, each violation on its line, and whether the scenario expected it."""
    lines = [f"  status: {status}" + (f" ({len(violations)} promise{'s' * (len(violations) > 1)} broken)"
                                      if violations else "")]
    lines += [f"    {v['kind']}: {printable(v['message'])}" for v in violations]
    if expected is not None:
        if expected["met"]:
            lines.append(f"  as the scenario expects ({expected['status']}: {', '.join(expected['violations'])})")
        else:
            lines.append(f"  NOT as the scenario expects ({expected['status']}: "
                         f"{', '.join(expected['violations']) or 'none'}); unexpected: "
                         f"{', '.join(expected['unexpected']) or 'none'}; missing: "
                         f"{', '.join(expected['missing']) or 'none'}")
    return lines


def _sweep(args) -> None:
    """The sweep command: run (or with --dry-run, list) the sweep's runs."""
    from simbench.commands.sweep import cluster, load_sweep, run_sweep

    cluster.check_where(args.workers, args.ray)
    sweep = load_sweep(args.sweep)
    if args.dry_run:
        listing, refused = _dry_run(sweep, args.allow_code)
        _say(listing)
        _refuse_all_bad_input(sweep, refused)
        return
    result = run_sweep(sweep, args.out, workers=args.workers, ray=args.ray, force=args.force,
                       progress=not args.quiet, allow_code=args.allow_code)
    if not args.quiet:
        counts = ", ".join(f"{n} {status}" for status, n in result.summary["status"].items() if n)
        _say(f"{sweep.name}: {result.summary['runs']} runs ({counts}"
             f"{f'; {result.resumed} from an earlier start' if result.resumed else ''}) in "
             f"{result.summary['wall_time']:.1f} s on {result.summary['backend']} -> {result.out / 'results.csv'}")
        for note in result.summary["notes"]:
            _say(f"  note: {note}")
    table = result.table
    _refuse_all_bad_input(sweep, [(i, e) for i, s, e in zip(table["id"], table["status"], table["error"])
                                  if s == "bad_input"])


def _refuse_all_bad_input(sweep, refused: list[tuple[str, str]]) -> None:
    """A sweep whose every run is bad input is bad input itself (exit 2); some refused among others is fine."""
    if refused and len(refused) == len(sweep.variants):
        run_id, detail = refused[0]
        raise ScenarioError(sweep.source, None, f"every one of its {len(refused)} runs is bad input (the first, "
                                                f"{run_id}: {detail})")


def _compare(args) -> None:
    """The compare command: the table and plots of every method, and the table on screen."""
    from simbench.commands.compare import compare
    from simbench.scenario import load_scenario

    out = args.out or Path("renders") / "compare" / load_scenario(args.scenario).name  # as run's renders/<name>/
    result = compare(args.scenario, args.planners, args.controllers, out, force=args.force,
                     progress=not args.quiet, allow_code=args.allow_code, plot_format=args.plot_format,
                     methods=args.methods)
    _say((result.out / "comparison.md").read_text())
    _say(f"table, plots and index.html in {result.out}")


def _dry_run(sweep, allow_code: bool) -> tuple[str, list[tuple[str, str]]]:
    """The listing of a sweep's runs and parameters, and the (run id, reason) of those the sweep would refuse: the
    schema's, and without `allow_code` a policy that names a module."""
    from simbench.physics.policy import refuse_code
    from simbench.scenario import parse_scenario

    lines = [f"{sweep.name}: {len(sweep.variants)} runs of {sweep.base}"]
    refused = []
    for v in sweep.variants:
        try:
            refuse_code(parse_scenario(v.document, v.id), allow_code)
            verdict = ""
        except ScenarioError as err:
            verdict = f"  -> bad_input: {err.detail}"
            refused.append((v.id, err.detail))
        lines.append(f"  {v.id} " + ", ".join(f"{name}={value!r}" for name, value in v.params.items()) + verdict)
    return "\n".join(lines), refused


def _validate(paths: list[Path], plan: bool, failed) -> int:
    """Check each scenario and, if `plan`, plan it, a bad one not stopping the next (`failed` prints its line
    and gives its code); 2 if any is bad input, else 1 if any failed, else EXIT_LIMITS if a plan breaks an
    unexpected promise."""
    codes = set()
    for path in paths:
        try:
            codes.add(_validate_one(path, plan))
        except Exception as err:
            code = failed(err)
            if code not in (1, 2):  # interrupted, or the output's reader went away: stop here
                return code
            codes.add(code)
    return next((code for code in (2, 1, EXIT_LIMITS) if code in codes), 0)


def _validate_one(path: Path, plan: bool) -> int:
    """Check one scenario and, if `plan`, plan it; EXIT_LIMITS if its plan breaks an unexpected promise."""
    from simbench import scenario
    from simbench.commands import pipeline

    sc = scenario.load_scenario(path)
    valid = f"{path}: valid ({sc.robot}, {sc.planner}, {sc.timing.duration:g} s)"
    code = 0
    if plan:
        traj, verdict = pipeline.check_plan(sc)
        _say(f"{valid}; plan: {verdict.status}")
        if verdict.violations or verdict.expected is not None:
            _say("\n".join(_status_lines(verdict.status, list(verdict.violations), verdict.expected)[1:]))
        for warning in traj.warnings:
            _say(f"  plan warning: {printable(warning)}")
        code = 0 if verdict.as_expected else EXIT_LIMITS
    else:
        _say(valid)
    _note_code(sc)
    return code


def _note_code(sc) -> None:
    """A note where the scenario's policy names a module, which run refuses without --allow-code."""
    from simbench.physics.policy import is_code

    target = getattr(sc.control, "policy", None)
    if target is not None and is_code(target):
        _say(f"  note: control.policy {target} names Python code: run, sweep and compare import and run it only "
             "with --allow-code")


def _run(args) -> int:
    """The run command: run the scenario and print its summary."""
    from simbench import scenario
    from simbench.commands import pipeline

    sc = scenario.load_scenario(args.scenario)
    out = args.out if args.out is not None else Path("renders") / sc.name
    try:
        result = pipeline.run(sc, out=out, video=not args.no_video, progress=not args.quiet, force=args.force,
                              allow_code=args.allow_code, plot_format=args.plot_format)
    except PhysicsError as err:
        kept = "the report and the timeseries up to then are" if err.recording is not None else "the report is"
        if err.recording is not None and args.timeseries:
            _export(out, args.timeseries, sc.robot_def.kinds, quiet=True)
        raise RunError(f"{err}; {kept} in {out}") from None
    if not args.quiet:
        _say(_summary(result))
    elif not result.evaluation.verdict.as_expected:  # errors only: the broken promises are errors
        _say("\n".join(_status_lines(result.report["status"], result.report["violations"],
                                     result.report.get("expected"))), file=sys.stderr)
    if args.timeseries:
        _export(result.out, args.timeseries, sc.robot_def.kinds, args.quiet)
    return 0 if result.evaluation.verdict.as_expected else EXIT_LIMITS


def _export(folder: Path, fmt: str = "csv", kinds: tuple[str, ...] | None = None, quiet: bool = False) -> None:
    """Write the run folder's timeseries in `fmt` and say where, and what it left out."""
    from simbench.outputs.export import export  # imported here: the command line loads without NumPy and MuJoCo

    written = export(folder, fmt, kinds)
    if not quiet:
        _say(f"{written.path}: {written.rows} rows, {len(written.columns)} columns")
        for name in written.left_out:
            _say(f"  note: {name} left out: not one number a sample")


def _list() -> str:
    """The registered plugins with their origins and broken entry points (a planner's robots, and the extra it
    needs, if any), then the shipped scenarios and sweeps."""
    from simbench.api import registry
    from simbench.core import extras

    lines = []
    for kind, found, width in (("robot", registry.robots, 16), ("planner", registry.planners, 20),
                               ("controller", registry.controllers, 20), ("policy", registry.policies, 20),
                               ("metric", registry.metrics, 20)):
        lines.append(f"{found.__name__}:")
        for x in found().values():
            works = f" [{_works(x)}]" if kind == "planner" else ""
            needs = extras.mark(x.name) if kind == "planner" else None
            works += f" [{needs}]" if needs else ""
            lines.append(f"  {x.name:{width}s} {x.description}{works} ({registry.origin(kind, x.name)})")
        lines += [f"  {name:20s} BROKEN: {printable(why)}" for name, why in sorted(registry.broken(kind).items())]
    for title, root in (("scenarios", scenarios_dir()), ("sweeps", sweeps_dir())):
        lines.append(f"{title}:")
        lines += [f"  {path.relative_to(root.parent)}" for path in sorted(root.rglob("*.yaml"))]
    return "\n".join(lines)


def _works(planner) -> str:
    """The robots a planner works with, in words."""
    return ", ".join(planner.robots) if planner.robots else "any robot" + (
        f" with {', '.join(planner.needs)}" if planner.needs else "")


def _interrupted(args, ctrl_c: interrupts.CtrlC) -> int:
    resume = ("; the finished runs are kept: run the same command again to resume"
              if args.command in ("sweep", "bench") else "")
    _say(f"interrupted{resume}", file=sys.stderr)
    return ctrl_c.exit_code


def exit_with(code: int) -> NoReturn:
    """End the `simbench` process with main's exit code. An interrupted command (130, 143) ends here, its clean-up
    done and its output flushed, without Python's finalization: an interrupt can leave MuJoCo's objects half made
    (a model read on a thread of its own: robots.model_file.interruptible), and finalizing them crashed the process
    now and then (SIGSEGV after its last line: tests/core/test_model_hardening.py's signals while a model loads)."""
    if code in (128 + signal.SIGINT, 128 + signal.SIGTERM):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def entry() -> NoReturn:
    """The `simbench` command (the console script): main, then exit_with its code."""
    exit_with(main())


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit code."""
    with interrupts.raising_interrupted() as ctrl_c:
        try:
            args = _parser().parse_args(_values_joined(sys.argv[1:] if argv is None else argv))
            with interrupts.held_back():  # imported here, so that --help loads neither psutil nor filelock
                from simbench.core.destination import command_line
        except interrupts.Interrupted:  # pressed while the command line was read
            _say("interrupted", file=sys.stderr)
            return ctrl_c.exit_code
        with command_line():
            return _command(args, ctrl_c)


_NUMBERS = re.compile(r"-[\d.][\d.eE+\-, ]*")  # a list of numbers that begins with a minus sign


def _values_joined(argv: list[str]) -> list[str]:
    """`--at -0.2,0.3` as `--at=-0.2,0.3`: argparse takes a value that begins with a minus sign (and holds more
    than a number) for an option."""
    out, i = [], 0
    while i < len(argv):
        if argv[i] == "--at" and i + 1 < len(argv) and _NUMBERS.fullmatch(argv[i + 1]):
            out.append(f"--at={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def _command(args: argparse.Namespace, ctrl_c: interrupts.CtrlC) -> int:
    """Run the command; its exit code, and for a failure its one line on stderr."""
    try:
        _preload(ctrl_c)
        if args.command == "list":
            _say(_list())
        elif args.command == "inspect":
            from simbench.commands.inspect_arm import inspect

            _say(inspect(args.model, args.at, args.units, args.json))
        elif args.command == "train-fk":
            from simbench.planners import learnt_fk

            learnt_fk.train(args.samples, tuple(args.hidden), args.seed, args.out or learnt_fk.WEIGHTS)
        elif args.command == "sweep":
            _sweep(args)
        elif args.command == "bench":
            bench_command.run(args, _say)
        elif args.command == "reproduce":
            from simbench.commands.reproduce import reproduce

            _say("\n".join(reproduce(args.paper, args.out, force=args.force).lines()))
        elif args.command == "compare":
            _compare(args)
        elif args.command == "export":
            _export(args.run_folder, args.format)
        elif args.command == "validate":
            return _validate(args.scenarios, not args.no_plan, lambda err: _failed(args, ctrl_c, err))
        else:
            return _run(args)
    except (KeyboardInterrupt, SystemExit) as err:
        if interrupts.is_press(err):
            return _interrupted(args, ctrl_c)
        # Not simbench's (it raises neither): an outside planner, robot or controller exiting or raising it.
        return _failed(args, ctrl_c, RunError(f"outside code simbench called raised {described(err)}"))
    except Exception as err:
        return _failed(args, ctrl_c, err)
    return 0


def _preload(ctrl_c: interrupts.CtrlC) -> None:
    """Import simbench's own modules with Ctrl-C held back (extension modules would swallow it), then outside
    entry points with it deliverable, so that a hanging one can be stopped."""
    with interrupts.held_back():
        from simbench import scenario  # noqa: F401
        from simbench.api import registry
        from simbench.commands import pipeline  # noqa: F401

        registry.load_shipped()
    registry.robots(), registry.planners(), registry.controllers(), registry.policies(), registry.metrics()
    if ctrl_c.pressed:
        raise interrupts.Interrupted


def _failed(args: argparse.Namespace, ctrl_c: interrupts.CtrlC, err: Exception) -> int:
    """Print why the command failed; its exit code (130 where Ctrl-C came first and caused `err`)."""
    if ctrl_c.pressed:
        return _interrupted(args, ctrl_c)
    if isinstance(err, BrokenPipeError):  # `simbench list | head`: quiet, as SIGPIPE ends a shell tool (128 + 13)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so that the last flush cannot fail too
        return 141
    for kind, prefix, code in ((ScenarioError, "error", 2), (OutputError, "error", 1), (RunError, "run failed", 1)):
        if isinstance(err, kind):  # OutputError before RunError, whose subclass it is
            _say(f"{prefix}: {err}", file=sys.stderr)
            return code
    if isinstance(err, OSError) and err.filename is not None:  # a file system refusal no module wrapped
        path, words = os_error_line(err)
        _say(f"error: {path}: {words}", file=sys.stderr)
        return 1 if err.errno in NO_SPACE else 2  # bad input, unless out of space
    if os.environ.get("SIMBENCH_DEBUG"):  # a bug: one line, unless asked for the traceback
        raise err
    _say(f"internal error: {type(err).__name__}: {printable(str(err))} (a bug in simbench: please report it with "
         "the input; SIMBENCH_DEBUG=1 shows the traceback)", file=sys.stderr)
    return 1
