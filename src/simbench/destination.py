"""Where a run or a sweep writes: never over anything simbench did not write, one writer at a time, nothing left
behind by a writer that was killed (project issue 11).

Every folder simbench writes holds a marker, `.simbench`, listing the files it wrote there (a sweep's marker
lists the names of its layout instead, since its rows arrive one by one). `--force` replaces a folder only if
every file in it is one the marker lists; a folder that holds the input, or the working folder, is never
replaced. A lock file beside the folder (`.<name>.lock`, flock) keeps a second writer out; the kernel lets go of
it when its holder dies, however it dies.
"""

from __future__ import annotations

import errno
import fcntl
import glob
import json
import os
import shutil
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from simbench.errors import ScenarioError, destination_error, name_max

MARKER = ".simbench"
# The longest suffix this process writes under beside a destination: `.<name>.partial-<pid>` (simbench.atomic).
_HIDDEN = len(".") + len(".partial-") + len(str(2**22))


@contextmanager
def refused(out: Path, what: str = "the output folder") -> Iterator[None]:
    """Turn an OSError met while looking at or preparing `out` into the error a user reads (errors.
    destination_error): the file system's reason in words, naming `out`; exit 2, or 1 for a full disk."""
    try:
        yield
    except OSError as err:
        raise destination_error(out, err, what) from None


def mark(folder: Path, names: Iterable[str] | None = None) -> None:
    """Write the marker of a folder simbench wrote: `names` (a layout), or every file now in it."""
    if names is None:
        names = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())
    (folder / MARKER).write_text(json.dumps({"written_by": "simbench", "files": list(names)}) + "\n")


def foreign(folder: Path) -> list[Path]:
    """The files in `folder` that its marker does not account for (all of them if it has none). A listed name
    accounts for itself and, if it is a folder, for what is in it."""
    try:
        listed = set(json.loads((folder / MARKER).read_text())["files"])
    except (OSError, ValueError, KeyError, TypeError):
        listed = set()
    out = []
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder)
        if path.is_dir() and not path.is_symlink() or rel.as_posix() == MARKER:
            continue
        if not any(rel.as_posix() == name or name in (p.as_posix() for p in rel.parents) for name in listed):
            out.append(path)
    return out


def check_inputs(out: Path, inputs: Iterable[Path]) -> None:
    """ScenarioError (naming `out`) if `out` is or holds an input or the working folder, is a file, or is a
    symlink that leads nowhere (broken, or a loop)."""
    with refused(out):
        if out.is_symlink() and not out.exists():
            what = "a symlink loop (too many levels of symbolic links)" if _loops(out) else \
                "a broken symlink (it points to nothing)"
            raise ScenarioError(str(out), None, f"{what}; pick another --out")
        try:
            where = out.resolve()
            cwd = Path.cwd().resolve()
        except RuntimeError:  # Python 3.11's resolve() on a symlink loop above `out`
            raise ScenarioError(str(out), None, "a symlink loop (too many levels of symbolic links); pick another "
                                                "--out") from None
        for thing, what in [*((Path(p), f"the input {p}") for p in inputs), (cwd, "the working folder")]:
            target = thing.resolve()
            if target == where or where in target.parents:
                raise ScenarioError(str(out), None, f"holds {what}: simbench never writes over it; pick another "
                                                    "--out")
        if out.exists() and not out.is_dir():
            raise ScenarioError(str(out), None, "is a file, not a folder; pick another --out")


def _loops(path: Path) -> bool:
    """Whether following the symlink `path` goes round in a loop."""
    try:
        os.stat(path)
    except OSError as err:
        return err.errno == errno.ELOOP
    return False


def check_replace(out: Path) -> None:
    """ScenarioError (naming `out`) unless simbench wrote every file in `out`, so that --force may replace it."""
    with refused(out):
        strangers = foreign(out)
    if strangers:
        raise ScenarioError(str(out), None, f"holds {len(strangers)} file(s) simbench did not write (such as "
                                            f"{strangers[0].relative_to(out)}); --force replaces only simbench's "
                                            "own outputs: remove them yourself or pick another --out")


def check(out: Path, inputs: Iterable[Path], force: bool) -> None:
    """ScenarioError (naming `out`) unless a run's outputs may go to `out`: check_inputs, and a folder that holds
    anything is replaced only with `force` and only if simbench wrote everything in it."""
    check_inputs(out, inputs)
    with refused(out):
        holds = out.is_dir() and any(out.iterdir())
    if holds:
        if not force:
            raise ScenarioError(str(out), None, "the output folder exists; pass --force to replace it, or --out to "
                                                "write elsewhere")
        check_replace(out)


@contextmanager
def locked(out: Path) -> Iterator[None]:
    """Hold the lock of `out` for the block; ScenarioError if another writer holds it, or if the file system
    refuses the lock file (a read-only folder, a file in the way, a name too long: errors.destination_error).
    The lock file is removed when the block ends (a writer that locked it just before is told apart: its file is
    no longer the path's)."""
    check_name(out)
    path = out.parent / f".{out.name}.lock"
    with refused(out):
        out.parent.mkdir(parents=True, exist_ok=True)
        lock = open(path, "w")
    with lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            if os.stat(path).st_ino != os.fstat(lock.fileno()).st_ino:
                raise BlockingIOError
        except (BlockingIOError, FileNotFoundError):
            raise ScenarioError(str(out), None, "another simbench run or sweep is writing into this folder; wait "
                                                "for it to end or pass --out to write elsewhere") from None
        try:
            yield
        finally:
            path.unlink(missing_ok=True)


def check_name(out: Path) -> None:
    """ScenarioError (naming `out`) if its name is too long for the hidden names simbench writes beside it."""
    length, limit = len(os.fsencode(out.name)), name_max(out.parent) - _HIDDEN
    if length > limit:
        raise ScenarioError(str(out), None, f"name too long ({length} characters; at most {limit} for an output "
                                            "folder, which simbench first writes under a longer hidden name); pick "
                                            "another --out")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    return True


def sweep_leftovers(path: Path) -> None:
    """Remove what dead writers left beside `path`: `.<name>.partial-PID` and `.<name>.old-PID` whose process is
    gone (a writer killed by SIGKILL, or the machine stopping, cannot clean up after itself)."""
    for leftover in path.parent.glob(f".{glob.escape(path.name)}.*-*"):
        tag, _, pid = leftover.name.rpartition("-")
        if tag.endswith((".partial", ".old")) and pid.isdigit() and not _alive(int(pid)):
            if leftover.is_dir() and not leftover.is_symlink():
                shutil.rmtree(leftover, ignore_errors=True)
            else:
                leftover.unlink(missing_ok=True)
