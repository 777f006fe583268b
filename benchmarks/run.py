"""Run every benchmark and rewrite BENCHMARKS.md with the machine and the date: python -m benchmarks.run"""

from __future__ import annotations

from pathlib import Path

from benchmarks import (bench_agile_eye_crossing, bench_agile_eye_planning, bench_analysis, bench_control,
                        bench_planners, bench_puma_auto, bench_render, bench_rsmg_contacts, bench_run, bench_soak,
                        bench_startup, bench_sweep, bench_tracking)
from benchmarks.common import machine, today


def main() -> None:
    sections = [module.markdown(module.measure())
                for module in (bench_tracking, bench_render, bench_sweep, bench_planners, bench_puma_auto,
                               bench_agile_eye_crossing, bench_agile_eye_planning, bench_analysis, bench_control,
                               bench_run, bench_soak, bench_rsmg_contacts, bench_startup)]
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
