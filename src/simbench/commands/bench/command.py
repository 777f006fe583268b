"""The `bench` command: its arguments (added to the CLI's parser) and what it does with them."""

from __future__ import annotations

import argparse
from pathlib import Path

from simbench.core import extras
from simbench.core.errors import ScenarioError


def add_parser(sub) -> None:
    """`simbench bench SUITE [--tasks N] [--seed S] [--methods A,B] [--workers N | --ray ADDRESS] [--out DIR]
    [--force] [--quiet]`."""
    bench = sub.add_parser("bench", help="run a suite of random tasks near singularities by several methods, into a "
                                         "leaderboard")
    bench.add_argument("suite", help="a shipped suite (a robot's name: puma600, spherical_arm, planar3r, jaco, "
                                     "panda, ur3, ur5, ur10, xarm7, z1, so100; or all) or a suite file")
    bench.add_argument("--tasks", type=int, default=None, help="tasks per robot (default: the suite's, 30)")
    bench.add_argument("--seed", type=int, default=None, help="the tasks' seed (default: the suite's, 0)")
    bench.add_argument("--methods", default=None, help="methods to run, comma-separated (default: the suite's)")
    where = bench.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, help="runs at once (default: one per CPU)")
    where.add_argument("--ray", metavar="ADDRESS", default=None, help="run on a Ray cluster, as sweep's --ray")
    bench.add_argument("--out", type=Path, default=None, help="output folder (default renders/bench/<suite>/)")
    bench.add_argument("--force", action="store_true",
                       help="start over: replace whatever the output folder holds (default: resume)")
    bench.add_argument("--quiet", action="store_true", help="print nothing but errors")


def run(args: argparse.Namespace, say) -> None:
    """Run the suite; `say` prints a line."""
    from simbench.commands.bench import load_suite, run_bench
    from simbench.commands.sweep import cluster

    cluster.check_where(args.workers, args.ray)
    methods = None
    if args.methods is not None:
        methods = [m.strip() for m in args.methods.split(",")]
        if not all(methods):
            raise ScenarioError("--methods", None, f"expected method names separated by commas, got {args.methods!r}")
    suite = load_suite(args.suite).with_options(args.tasks, args.seed, methods)
    result = run_bench(suite, args.out, workers=args.workers, ray=args.ray, force=args.force,
                       progress=not args.quiet)
    if not args.quiet:
        summary = result.summary
        counts = ", ".join(f"{n} {status}" for status, n in summary["status"].items() if n)
        resumed = f"; {summary['resumed']} from an earlier start" if summary["resumed"] else ""
        say(f"{suite.name}: {summary['runs']} runs ({counts}{resumed}) in {summary['wall_time']:.1f} s on "
            f"{summary['backend']} -> {result.out / 'leaderboard.csv'}")
        no_parquet = extras.missing("pyarrow", "runs.parquet")
        if no_parquet:
            say(f"  note: {no_parquet}")
