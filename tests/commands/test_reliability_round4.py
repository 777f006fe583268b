"""Reliability, fourth round: a local Ray cluster on the loopback address alone, the bench's --seed bounded as a
suite file's, a suite's own arm with a bad name named so, `list` marking what needs an extra, Ctrl-C while
`python -m simbench` imports, `sweep --dry-run` marking a policy module without --allow-code, and the CEM
example's bad arguments in one line."""

from __future__ import annotations

import csv
import ipaddress
import subprocess
import sys
from pathlib import Path

import psutil
import pytest
import yaml

from simbench.cli import main

ROOT = Path(__file__).resolve().parents[2]


def _listening(process: psutil.Process) -> set[str]:
    """The addresses that `process` and its descendants accept connections on."""
    found = set()
    for p in [process, *process.children(recursive=True)]:
        try:
            found |= {c.laddr.ip for c in p.net_connections(kind="inet") if c.status == psutil.CONN_LISTEN}
        except psutil.Error:  # ended meanwhile
            continue
    return found


def _loopback(address: str) -> bool:
    """Whether `address` is a loopback one, an IPv4 one written as IPv6 (::ffff:127.0.0.1) included."""
    ip = ipaddress.ip_address(address)
    return (getattr(ip, "ipv4_mapped", None) or ip).is_loopback


def test_a_local_ray_cluster_is_on_the_loopback_address_alone(tmp_path, monkeypatch):
    """`sweep --ray local` (as the suite's Ray sweep, two workers) starts a cluster whose node, GCS and every
    listening socket are on 127.0.0.1: Ray on Linux otherwise takes the network interface's address and opens its
    services there. Seen from outside the code: Ray's own view of the live cluster and the sockets the processes
    hold, read just before simbench stops it."""
    ray = pytest.importorskip("ray", reason="the Ray extra is part of [test]; this check needs it")
    seen = {}
    shutdown = ray.shutdown

    def seen_then_shut_down(*args, **kwargs):
        seen["nodes"] = {node["NodeManagerAddress"] for node in ray.nodes()}
        seen["gcs"] = ray.get_runtime_context().gcs_address.rpartition(":")[0]
        seen["listening"] = _listening(psutil.Process())
        return shutdown(*args, **kwargs)

    monkeypatch.setattr(ray, "shutdown", seen_then_shut_down)
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({"base": "spherical_arm/case1", "outputs": "none",
                                     "grid": {"timing.law": ["cubic", "quintic"]}}))
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--ray", "local", "--workers", "2",
                 "--quiet"]) == 0
    assert seen["nodes"] == {"127.0.0.1"} and seen["gcs"] == "127.0.0.1", seen
    assert seen["listening"] and all(map(_loopback, seen["listening"])), seen["listening"]
    assert not ray.is_initialized()


# --- the bench's --seed, and a suite's own arm with a bad name ----------------------------------------------------

def _error_line(capsys, argv: list[str]) -> str:
    """The one line on stderr of the command, which exits 2 (bad input)."""
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err.strip()


def test_bench_refuses_a_seed_a_suite_file_refuses(tmp_path, capsys):
    """2^63 and above: a suite file's seed: is refused so (the schema), and --seed now the same way, before any
    run (it used to run the suite)."""
    too_big = 2**63
    suite = tmp_path / "suite.yaml"
    suite.write_text(yaml.safe_dump({"seed": too_big, "robots": ["puma600"]}))
    assert _error_line(capsys, ["bench", str(suite)]).startswith(f"error: {suite}: seed: expected ")
    out = tmp_path / "out"
    for seed in (too_big, 99999999999999999999999, -1):
        line = _error_line(capsys, ["bench", "puma600", "--seed", str(seed), "--tasks", "1", "--out", str(out)])
        assert line == f"error: --seed: expected a seed from 0 to {too_big - 1} (2^63 - 1), got {seed}"
    assert not out.exists()


NAME_RULE = "expected letters, digits, '_', '.' or '-', starting with a letter or digit (it names the output folder)"


@pytest.mark.parametrize("name, says", [("<script>x</script>", f"{NAME_RULE}, got '<script>x</script>'"),
                                        ("\x1b[31mred", f"{NAME_RULE}, got '\\x1b[31mred'"),
                                        (5, "expected a valid string, got 5")])
def test_a_suite_arm_with_a_bad_name_is_refused_for_what_its_name_is(tmp_path, capsys, name, says):
    """An arm of the suite file's own whose name cannot name its rows is refused saying what is wrong with the name
    (it was 'not given, and the file's name cannot stand in for it'), control characters escaped."""
    suite = tmp_path / "suite.yaml"
    suite.write_text(yaml.safe_dump({"robots": [{"name": name, "model": "arm.xml"}]}))
    assert _error_line(capsys, ["bench", str(suite)]) == f"error: {suite}: robots[0].name: {says}"


# --- `simbench list` marks what needs an extra --------------------------------------------------------------------

def _needs_in_code() -> dict[str, set[str]]:
    """The extras each of simbench's own planners calls for, read from its code: every extras.require or
    extras.missing call with a module's name in the planner's module or package."""
    import ast

    from simbench.api import registry

    planners = ROOT / "src" / "simbench" / "planners"
    found: dict[str, set[str]] = {}
    for path in planners.rglob("*.py"):
        name = path.relative_to(planners).parts[0].removesuffix(".py")
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr in ("require", "missing") and getattr(node.func.value, "id", "") == "extras"):
                found.setdefault(name, set()).add(node.args[0].value)
    return {name: modules for name, modules in found.items() if name in registry.planners()}


def test_list_marks_each_planner_that_needs_an_extra(capsys, monkeypatch):
    """Each planner whose code calls for an optional package is marked in `simbench list` with that package,
    installed, or not installed and the pip command (the package made unimportable); the others are not marked."""
    from simbench.core import extras

    needs = _needs_in_code()
    assert needs.keys() >= {"mink_baseline", "avoidance_4567", "cartesian_path"}, needs
    optional = set().union(*needs.values())
    for blocked in (False, True):
        if blocked:
            for module in optional:
                monkeypatch.setitem(sys.modules, module, None)
        assert main(["list"]) == 0
        listing = capsys.readouterr().out.splitlines()
        for line in listing[listing.index("planners:") + 1:listing.index("controllers:")]:
            marked = {m for m in optional if f"needs {extras.EXTRAS[m][1]}, " in line}
            assert marked == needs.get(line.split()[0], set()), line
            for module in marked:
                extra, package = extras.EXTRAS[module]
                state = f"not installed: pip install 'simbench[{extra}]'" if blocked else "installed"
                assert f"needs {package}, {state}]" in line, line


# --- Ctrl-C while `python -m simbench` imports ----------------------------------------------------------------------

# Ctrl-C pressed (SIGINT raised) the moment the command line's modules import simbench.outputs.plot_formats, before
# main can
# answer it; then `python -m simbench list` as the interpreter runs it.
PRESSED_WHILE_IMPORTING = """
import importlib.abc, runpy, signal, sys

class Press(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "simbench.outputs.plot_formats":
            signal.raise_signal(signal.SIGINT)
        return None

sys.meta_path.insert(0, Press())
sys.argv = ["simbench", "list"]
runpy.run_module("simbench", run_name="__main__", alter_sys=True)
"""


def test_ctrl_c_while_python_m_simbench_imports_is_one_line_and_exit_130(tmp_path):
    """Ctrl-C before main (its imports under way) ends as one during the command: 'interrupted', exit 130, no
    traceback (it was a KeyboardInterrupt's)."""
    import signal

    done = subprocess.run([sys.executable, "-c", PRESSED_WHILE_IMPORTING], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert (done.returncode, done.stdout, done.stderr) == (130, "", "interrupted\n")


# --- `sweep --dry-run` and a policy that names a module -----------------------------------------------------------

def test_dry_run_marks_a_policy_module_that_needs_allow_code(tmp_path, capsys):
    """A run whose control.policy names a module is marked bad_input by --dry-run without --allow-code, with the
    words the sweep itself refuses it with (its row's error), and every run so marked exits 2 as the sweep does;
    with --allow-code it is not marked, and nothing is imported either way."""
    from simbench_planar3r import control

    marker = tmp_path / "userpolicy.imported"
    (tmp_path / "userpolicy.py").write_text(f"open({str(marker)!r}, 'w')\ndef make(scenario):\n    pass\n")
    base = yaml.safe_load((Path(control.__file__).parent / "scenarios" / "line_policy.yaml").read_text())
    base["control"] = {"controller": "policy", "policy": "joint_pd_policy", "action": "torque"}
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base))
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({"base": "base.yaml", "outputs": "none",
                                     "grid": {"control.policy": ["userpolicy:make"]}}))
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--workers", "1", "--quiet"]) == 2
    row = next(csv.DictReader((tmp_path / "out" / "results.csv").open()))
    assert row["status"] == "bad_input" and "--allow-code" in row["error"]
    refused = capsys.readouterr().err

    assert main(["sweep", str(sweep), "--dry-run"]) == 2
    said = capsys.readouterr()
    assert f"  {row['id']} control.policy='userpolicy:make'  -> bad_input: {row['error']}\n" in said.out, said.out
    assert said.err == refused
    assert main(["sweep", str(sweep), "--dry-run", "--allow-code"]) == 0
    said = capsys.readouterr()
    assert "control.policy='userpolicy:make'" in said.out and "bad_input" not in said.out, said.out
    assert not marker.exists()


# --- the CEM example's bad arguments ----------------------------------------------------------------------------

@pytest.mark.parametrize("argv, says", [
    (["--iterations", "0"], "argument --iterations: expected an integer >= 1, got '0'"),
    (["--population", "1"], "argument --population: expected an integer >= 2, got '1'"),
    (["--population", "4", "--elite", "5"], "argument --elite: expected at most --population (4), got 5"),
    (["--seed", "-1"], "argument --seed: expected an integer >= 0, got '-1'"),
    (["--task", "puma600"], "argument --task: expected a shipped task (agile_eye/avoidance, "),
    (["--task", "nosuch/line"], "argument --task: expected a shipped task (agile_eye/avoidance, "),
    (["--out", "file/curves"], "argument --out: cannot make 'file/curves': Not a directory")])
def test_the_cem_example_refuses_bad_arguments_in_one_line(tmp_path, argv, says):
    """Each bad argument of examples/rl_cem/train.py: one line naming it, exit 2, before any episode (they were
    tracebacks, --iterations 0 after the reference's episode)."""
    (tmp_path / "file").write_text("")
    done = subprocess.run([sys.executable, str(ROOT / "examples" / "rl_cem" / "train.py"), *argv], text=True,
                          capture_output=True, cwd=tmp_path, timeout=120)
    assert (done.returncode, done.stdout) == (2, ""), done.stderr
    assert done.stderr.startswith(f"train.py: error: {says}") and len(done.stderr.splitlines()) == 1, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]
