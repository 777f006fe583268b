"""Run every benchmark and rewrite BENCHMARKS.md with the machine and the date: python -m benchmarks.run"""

from __future__ import annotations

from pathlib import Path

from benchmarks import bench_planners, bench_run, bench_tracking
from benchmarks.common import machine, today


def main() -> None:
    sections = [bench_tracking.markdown(bench_tracking.measure()), bench_planners.markdown(bench_planners.measure()),
                bench_run.markdown(bench_run.measure())]
    text = "\n\n".join([
        "# Benchmarks",
        "Written by `python -m benchmarks.run` (from the repository root, in the test environment).",
        f"Machine: {machine()}.  \nDate: {today()}.",
        *sections,
    ]) + "\n"
    Path(__file__).resolve().parents[1].joinpath("BENCHMARKS.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
