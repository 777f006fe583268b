"""Each paper's published results regenerated beside the printed ones: `reproduce(paper, out)` writes out/<paper>/.

A difference is a typo in the paper (its own other values show it), an error in the paper (a number shows the
method or equation does not do what the paper says), or ours (simbench departs, or cannot tell why). Each module
paper000 ... paper003 writes its tables and figures and returns its part of the Summary. Folders are guarded and
written as a run's are (destination.locked, atomic.staged_folder).
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, replace
from pathlib import Path

from simbench.commands.reproduce._common import CLASSES, ERROR, OURS, TYPO, Difference, PaperSummary
from simbench.core import destination
from simbench.core.atomic import staged_folder
from simbench.core.errors import STAGED, ScenarioError
from simbench.core.resources import scenarios_dir

__all__ = ["CLASSES", "ERROR", "OURS", "PAPERS", "TYPO", "Difference", "PaperSummary", "Summary", "reproduce"]

PAPERS = ("000", "001", "002", "003")


@dataclass(frozen=True)
class Summary:
    """What `reproduce` found: one PaperSummary a paper, where they were written and how long it took."""

    out: Path
    papers: tuple[PaperSummary, ...]
    seconds: float

    def paper(self, name: str) -> PaperSummary:
        """The part of one paper ('000' ...)."""
        return next(p for p in self.papers if p.paper == name)

    def counts(self) -> dict[str, int]:
        """Differences of each class over every paper."""
        return {k: sum(p.count(k) for p in self.papers) for k in CLASSES}

    def lines(self) -> list[str]:
        """A one-screen summary: per paper the values reproduced, the differences by class, its headline."""
        out = [f"simbench reproduce: {len(self.papers)} paper(s) into {self.out} in {self.seconds:.1f} s"]
        for p in self.papers:
            counts = ", ".join(f"{k} {p.count(k)}" for k in CLASSES)
            out.append(f"{p.paper} {p.title}: {p.reproduced} of {p.compared} printed values and claims reproduced; "
                       f"differences: {counts}")
            out += [f"    {line}" for line in p.headline[:4]]
        total = self.counts()
        out.append("all papers, differences: " + ", ".join(f"{k} {total[k]}" for k in CLASSES)
                   + f"; tables and figures in {self.out}/<paper>/ (summary.md, differences.md)")
        return out


def _papers(paper: str) -> tuple[str, ...]:
    if paper != "all" and paper not in PAPERS:
        raise ValueError(f"paper must be one of {', '.join(PAPERS)} or all, not {paper!r}")
    return PAPERS if paper == "all" else (paper,)


def reproduce(paper: str, out: Path, force: bool = False, log: Callable[[str], None] | None = None) -> Summary:
    """Regenerate a paper's printed results beside simbench's, every difference classified.

    Args:
        paper: `"000"` ... `"003"`, or `"all"`.
        out: The folder; each paper is written into `out/<paper>/`.
        force: Replace folders that hold something, but only where simbench wrote all of it (every folder is
            checked before any is written).
        log: Called with a line as each paper starts and ends.

    Returns:
        Each paper's part of the summary, where they were written and how long it took.

    Raises:
        ScenarioError: an unknown paper, an `out` that holds anything but reproductions, or a folder that holds
            something without `force`.
    """
    names = _papers(paper)
    out = destination.followed(Path(out))
    _check_own(out)
    folders = {name: destination.followed(out / name) for name in names}
    start = time.perf_counter()
    parts = []
    with ExitStack() as stack:
        for name in names:
            stack.enter_context(destination.locked(folders[name]))
        inputs = sorted(scenarios_dir().glob("*/*.yaml"))  # what the reproductions read: no folder may hold them
        for name in names:
            destination.check(folders[name], inputs, force)
        for name in names:
            module = importlib.import_module(f"simbench.commands.reproduce.paper{name}")
            if log:
                log(f"paper {name}: {module.TITLE} ...")
            began = time.perf_counter()
            with staged_folder(folders[name]) as tmp:
                part = module.reproduce(tmp)
            part = replace(part, seconds=time.perf_counter() - began)
            if log:
                log(f"paper {name}: done in {part.seconds:.1f} s")
            parts.append(part)
    return Summary(out, tuple(parts), time.perf_counter() - start)


def _check_own(out: Path) -> None:
    """ScenarioError unless `out` is a folder of reproductions' own: new, empty, or holding nothing but paper
    folders (000 ... 003) and simbench's hidden names beside them (their locks, staging folders). The papers are
    written into it as subfolders with their locks beside them: into `/` or a home folder, they would land among
    the user's own files."""
    ours = {*PAPERS, *(f".{name}.lock" for name in PAPERS)}
    with destination.refused(out):
        if not out.is_dir():
            return  # new (or a file, which the checks of its subfolders refuse)
        other = next((p.name for p in sorted(out.iterdir()) if p.name not in ours and not (
            (m := STAGED.match(p.name)) and m["name"] in PAPERS)), None)
    if other is not None:
        raise ScenarioError(str(out), None, f"holds {other}, which is not a reproduction: reproduce writes its "
                                            f"papers ({out / PAPERS[0]} ...) only into a folder of their own (new, "
                                            "empty, or holding only reproductions); pick another --out")
