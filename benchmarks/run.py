"""Run the benchmarks and write their results into BENCHMARKS.md: python -m benchmarks.run [bench_x ...]

With no names it runs every module of MODULES (each block states the seconds it took); with names, those alone. Each
module's results go into BENCHMARKS.md between two marker lines of its own (HTML comments, unseen on a rendered
page), stamped with the machine, the date, the time it took and the load average; everything outside the markers
(written by hand: the targets, what each module measures and how to rerun it, measurements taken by hand) is kept
byte for byte, so a rerun replaces the figures and never the notes. A module with no block yet gets one at the
end. The file is replaced whole, never left half-written.
"""

from __future__ import annotations

import importlib
import os
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import machine, today

MODULES = ("bench_tracking", "bench_render", "bench_sweep", "bench_planners", "bench_puma_auto",
           "bench_agile_eye_crossing", "bench_agile_eye_planning", "bench_analysis", "bench_control", "bench_run",
           "bench_plots", "bench_soak", "bench_rsmg_contacts", "bench_startup", "bench_random_lines", "bench_suite",
           "bench_env", "bench_arms", "bench_env_step", "bench_plan_cost")
TARGET = Path(__file__).resolve().parents[1] / "BENCHMARKS.md"
HEADER = ("# Benchmarks\n\nWritten by `python -m benchmarks.run` (from the repository root, in the test environment):\n"
          "each module's figures between its markers, with the machine, the date, the time and the load average\n"
          "they were measured with; the targets, each module's description and the measurements taken by hand\n"
          "around them.\n")


def begin(name: str) -> str:
    """The line that opens module `name`'s block."""
    return f"<!-- {name}: written by python -m benchmarks.run, replaced when it runs again -->"


def end(name: str) -> str:
    """The line that closes module `name`'s block."""
    return f"<!-- end of {name} -->"


def splice(text: str, name: str, section: str) -> str:
    """`text` with module `name`'s block holding `section`: in place of the block it has, or appended. A block
    whose markers are missing one of the pair, repeated or out of order is refused: replacing it would lose notes."""
    opening, closing = begin(name), end(name)
    first, last = text.find(opening), text.find(closing)
    block = f"{opening}\n{section.strip()}\n{closing}"
    if first < 0 and last < 0:
        return f"{text.rstrip()}\n\n{block}\n"
    if first < 0 or last < first or text.count(opening) > 1 or text.count(closing) > 1:
        raise ValueError(f"BENCHMARKS.md: the markers of {name} are not one pair, opening before closing; "
                         "mend them by hand")
    return text[:first] + block + text[last + len(closing):]


def stamped(markdown: str, measured_on: str, date: str, seconds: float, load: tuple[float, float]) -> str:
    """A module's markdown with what it was measured on, when, how long it took and the machine's load average
    (1 minute) before and after, under its title: a figure of a busy machine reads differently."""
    title, _, rest = markdown.strip().partition("\n")
    return (f"{title}\n\nMeasured on {measured_on}, {date}, in {seconds:.0f} s; load average {load[0]:.1f} before "
            f"and {load[1]:.1f} after.\n{rest}")


def write(path: Path, text: str) -> None:
    """Replace `path` with `text` at once (a file beside it, then renamed)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def main(names: list[str]) -> int:
    """Run the named modules (all when none), writing each one's block as it finishes."""
    unknown = [n for n in names if n not in MODULES]
    if unknown:
        print(f"benchmarks.run: unknown module {unknown[0]!r}; expected some of: {', '.join(MODULES)}",
              file=sys.stderr)
        return 2
    for name in names or MODULES:
        module = importlib.import_module(f"benchmarks.{name}")
        start, load = time.perf_counter(), os.getloadavg()[0]
        result = module.measure()
        section = stamped(module.markdown(result), machine(), today(), time.perf_counter() - start,
                          (load, os.getloadavg()[0]))
        text = TARGET.read_text() if TARGET.exists() else HEADER
        write(TARGET, splice(text, name, section))
        print(section, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
