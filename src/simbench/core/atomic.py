"""Writes that never leave a half-written file or folder: everything is written beside its destination under a
hidden name, then renamed into place (atomic within one filesystem). An OSError on the way becomes
errors.OutputError, naming the file as the user knows it and saying what was kept.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from simbench.core.destination import check_replace, mark, marked, remove, sweep_leftovers
from simbench.core.errors import OutputError, output_error, shown_path
from simbench.core.interrupts import held_back


def _beside(path: Path, tag: str) -> Path:
    """The hidden name under which this process writes or sets aside `path`."""
    return path.parent / f".{path.name}.{tag}-{os.getpid()}"


def write_text(path: Path, text: str) -> None:
    """Replace `path` with `text` (UTF-8, whatever the locale) in one step."""
    with staged_file(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def holds(path: Path, text: str) -> bool:
    """Whether `path` is a file (not a link) holding `text`: what need not be written again."""
    try:
        return not path.is_symlink() and path.read_text(encoding="utf-8") == text
    except (OSError, UnicodeDecodeError):
        return False


@contextmanager
def _writing(path: Path) -> Iterator[None]:
    """An OSError in the block as OutputError saying that `path` (the outermost write's) is as it was."""
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
    """A hidden path beside `path` to write to; moved onto `path` if the block succeeds, else removed."""
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
    """A fresh hidden folder beside `out`, moved onto `out` with its marker if the block succeeds, else removed.
    Its marker is written as it is made (what a killed writer leaves is then known as simbench's) and rewritten
    at the end. That `out` may be replaced is checked again before it is (a file of the user's may have come
    since)."""
    with _writing(out):
        out.parent.mkdir(parents=True, exist_ok=True)
        sweep_leftovers(out)
        tmp = _beside(out, "partial")
        if marked(tmp):  # under this process's id: left by a failed write of its own, or a dead process's
            remove(tmp)
        try:
            tmp.mkdir()  # inside the try: a Ctrl-C handled as mkdir returns still removes it
            mark(tmp, [])
            yield tmp
            mark(tmp)
            if out.exists():
                check_replace(out, removes=True)
        except BaseException:
            remove(tmp)
            raise
        _move(tmp, out)


def _move(tmp: Path, out: Path) -> None:
    """Put the folder `tmp` in place of `out`, the previous `out` set aside and put back if the move fails."""
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
        remove(tmp)
        raise
    remove(old)
