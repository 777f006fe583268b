"""Writes that never leave a half-written file or folder: a run or a sweep stopped at any instant, or refused by
the file system (a full disk), leaves the previous complete output, or none.

Everything is first written beside its destination under a hidden name, then moved into place with a rename,
which POSIX makes atomic within one filesystem. What a killed writer left under such a name is removed by the
next writer of the same path (destination.sweep_leftovers). An OSError met on the way (ENOSPC, EFBIG, EACCES)
becomes errors.OutputError, naming the file as the user knows it (not its hidden name) and saying what was kept.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from simbench.destination import check_replace, mark, sweep_leftovers
from simbench.errors import OutputError, output_error, shown_path
from simbench.interrupts import held_back


def _beside(path: Path, tag: str) -> Path:
    """The hidden name under which this process writes or sets aside `path`."""
    return path.parent / f".{path.name}.{tag}-{os.getpid()}"


def write_text(path: Path, text: str) -> None:
    """Replace `path` with `text` (UTF-8, whatever the locale) in one step."""
    with staged_file(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


@contextmanager
def _writing(path: Path) -> Iterator[None]:
    """Turn an OSError in the block into OutputError (errors.output_error) saying that `path` is as it was; one
    from a write nested in this one says so of this one's `path`, which is what the user asked for."""
    shown = shown_path(path)
    kept = f"the previous {shown} is kept" if os.path.exists(path) else f"nothing was written to {shown}"
    try:
        yield
    except OSError as err:
        raise output_error(err, path, kept) from None
    except OutputError as err:
        raise OutputError(err.path, err.problem, kept) from None


@contextmanager
def staged_file(path: Path) -> Iterator[Path]:
    """A hidden path beside `path` to write to; moved onto `path` if the block succeeds, removed if it fails
    (an OSError as OutputError)."""
    with _writing(path):
        sweep_leftovers(path)
        tmp = _beside(path, "partial")
        try:
            yield tmp
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)


@contextmanager
def staged_folder(out: Path) -> Iterator[Path]:
    """A fresh hidden folder beside `out`, moved onto `out` (with its marker, destination.mark) if the block
    succeeds, removed if it fails (an OSError as OutputError). The caller has checked that `out` may be replaced
    (destination.check); it is checked again before it is (a file of the user's put in since: ScenarioError)."""
    with _writing(out):
        out.parent.mkdir(parents=True, exist_ok=True)
        sweep_leftovers(out)
        tmp = _beside(out, "partial")
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
        try:
            yield tmp
            mark(tmp)
            if out.exists():
                check_replace(out)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        _move(tmp, out)


def _move(tmp: Path, out: Path) -> None:
    """Put the folder `tmp` in place of `out`, setting the previous `out` aside meanwhile and putting it back if
    the move fails; `tmp` is removed if it was not moved."""
    old = _beside(out, "old")
    try:
        with held_back():  # Ctrl-C between the two renames would leave neither folder in place
            moved_aside = out.exists()
            if moved_aside:
                out.rename(old)
            try:
                tmp.rename(out)
            except BaseException:
                if moved_aside:
                    old.rename(out)
                raise
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    shutil.rmtree(old, ignore_errors=True)
