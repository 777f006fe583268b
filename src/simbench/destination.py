"""Where a run or a sweep writes: never over anything simbench did not write, one writer at a time, nothing left
behind by a writer that was killed.

Every folder simbench writes holds a marker, `.simbench`, of JSON lines listing the files written there by
relative path (a sweep appends a line before each batch); `--force` replaces a folder only if markers account
for every file in it. A lock file beside the folder (`.<name>.lock`, an flock the kernel drops when its holder
dies) keeps a second writer out.
"""

from __future__ import annotations

import errno
import glob
import json
import os
import shutil
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

import psutil
from filelock import FileLock, Timeout

from simbench.errors import STAGED, ScenarioError, destination_error, name_max

MARKER = ".simbench"
# The longest suffix this process writes under beside a destination: `.<name>.partial-<pid>` (simbench.atomic).
_HIDDEN = len(".") + len(".partial-") + len(str(2**22))


@contextmanager
def refused(out: Path) -> Iterator[None]:
    """An OSError met while looking at or preparing `out` as errors.destination_error."""
    try:
        yield
    except OSError as err:
        raise destination_error(out, err) from None


def mark(folder: Path, names: Iterable[str] | None = None) -> None:
    """Write the marker of a folder simbench wrote: `names`, or every file now in it."""
    if names is None:
        names = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())
    (folder / MARKER).write_text(json.dumps({"written_by": "simbench", "files": list(names)}) + "\n")


def mark_more(folder: Path, names: Iterable[str]) -> None:
    """Append `names` to the marker of `folder` before those files are written, so that a writer stopped in
    between leaves a name listed, never a file unlisted."""
    names = list(names)
    line = (json.dumps({"files": names}) + "\n").encode()
    try:
        fd = os.open(folder / MARKER, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW, 0o644)
        try:
            os.write(fd, line)
        finally:
            os.close(fd)
    except OSError as err:
        raise OSError(err.errno, err.strerror, str(folder / names[0])) from None


def _listed(folder: Path) -> set[str]:
    """The paths the marker of `folder` lists (unreadable lines skipped)."""
    try:
        text = (folder / MARKER).read_text()
    except OSError:
        return set()
    names: set[str] = set()
    for line in text.splitlines():
        try:
            files = json.loads(line)["files"]
        except (ValueError, KeyError, TypeError):
            continue
        if isinstance(files, list):
            names.update(name for name in files if isinstance(name, str))
    return names


def foreign(folder: Path) -> list[Path]:
    """The files in `folder`, at every depth, that no marker on the way down lists (staging folders and their
    contents, and empty lock files, excepted: a sweep's worker killed mid-run leaves them in runs/)."""
    listed: dict[Path, set[str]] = {}
    out = []
    for path in _files(folder):
        owners = [path.parent, *(p for p in path.parent.parents if folder in p.parents or p == folder)]
        if not any(path.relative_to(owner).as_posix() in listed.setdefault(owner, _listed(owner))
                   for owner in owners):
            out.append(path)
    return out


def _leftover(path: Path, folder: Path) -> bool:
    """Whether `path` (in `folder`) is or lies in a staging folder, or is an empty lock file (`.<name>.lock`)."""
    if any(_staging_pid(part) is not None for part in path.relative_to(folder).parts):
        return True
    name = path.name
    return (name.startswith(".") and name.endswith(".lock") and len(name) > len("..lock") and not path.is_symlink()
            and path.is_file() and path.stat().st_size == 0)


def _staging_pid(name: str) -> int | None:
    """The writer's process id if `name` is a staging name, `.<name>.partial-PID` or `.<name>.old-PID`."""
    m = STAGED.match(name)
    return int(m["pid"]) if m else None


def followed(out: Path) -> Path:
    """`out`, or where it leads if it is a symlink to a folder (the link itself stays as it was)."""
    try:
        return out.resolve() if out.is_symlink() and out.is_dir() else out
    except (OSError, RuntimeError):
        return out


def check_inputs(out: Path, inputs: Iterable[Path]) -> None:
    """ScenarioError if `out` is or holds an input or the working folder, is a file, or is a broken symlink."""
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


def check_replace(out: Path, why: str = "--force replaces only simbench's own outputs") -> None:
    """ScenarioError naming one stranger unless simbench wrote every file in `out`."""
    with refused(out):
        strangers = foreign(out)
        unmarked = None if strangers or (out / MARKER).is_file() else next(_files(out), None)
    if strangers:
        raise ScenarioError(str(out), None, f"holds {len(strangers)} file(s) simbench did not write (such as "
                                            f"{strangers[0].relative_to(out)}); {why}: move them out yourself or "
                                            "pick another --out")
    if unmarked is not None:  # outputs of other runs in its subfolders (renders/ itself, say): not one output
        raise ScenarioError(str(out), None, f"holds other runs' outputs (such as {unmarked.relative_to(out)}) and is "
                                            f"not itself a folder simbench wrote (no {MARKER} of its own); {why}: "
                                            "pick another --out")


def _files(folder: Path) -> Iterator[Path]:
    """The files in `folder`, at every depth, but markers and staging and lock leftovers."""
    return (path for path in sorted(folder.rglob("*")) if not (path.is_dir() and not path.is_symlink())
            and path.name != MARKER and not _leftover(path, folder))


def check(out: Path, inputs: Iterable[Path], force: bool) -> None:
    """ScenarioError unless outputs may go to `out`: a non-empty folder only with `force` and check_replace."""
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
    """Hold the lock of `out` for the block; ScenarioError if another writer holds it. The lock file is unlinked
    while still held (filelock refuses a writer that opened it just before)."""
    check_name(out)
    path = out.parent / f".{out.name}.lock"
    created = [p for p in (out.parent, *out.parent.parents) if not p.exists()]
    try:
        with refused(out):
            out.parent.mkdir(parents=True, exist_ok=True)
            lock = _take(path, out)
        try:
            yield
        finally:
            try:
                path.unlink(missing_ok=True)
            finally:
                lock.release()
    finally:
        if not out.exists():  # a run refused or failed before writing: the folders made for its lock go too
            _remove_empty(created)


def _remove_empty(folders: list[Path]) -> None:
    """Remove each of `folders` (deepest first) that is empty; stop at the first that is not."""
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:
            return


def _take(path: Path, out: Path) -> FileLock:
    """The lock at `path`, taken without waiting; ScenarioError if another writer has it or a symlink is there
    (filelock opens it with O_NOFOLLOW)."""
    lock = FileLock(path, blocking=False)
    try:
        lock.acquire()
    except Timeout:
        raise ScenarioError(str(out), None, "another simbench run or sweep is writing into this folder; wait for it "
                                            "to end or pass --out to write elsewhere") from None
    except OSError as err:
        if err.errno == errno.ELOOP and path.is_symlink():
            raise ScenarioError(str(path), None, "is a symlink where simbench keeps its lock file; simbench does "
                                                 "not follow it: remove it, or pass --out to write elsewhere") from None
        raise
    return lock


def check_name(out: Path) -> None:
    """ScenarioError if the name of `out` is too long for the staging names written beside it."""
    length, limit = len(os.fsencode(out.name)), name_max(out.parent) - _HIDDEN
    if length > limit:
        raise ScenarioError(str(out), None, f"name too long ({length} characters; at most {limit} for an output "
                                            "folder, which simbench first writes under a longer hidden name); pick "
                                            "another --out")


def sweep_leftovers(path: Path) -> None:
    """Remove the staging names beside `path` whose writer is dead (killed by SIGKILL, say)."""
    for leftover in path.parent.glob(f".{glob.escape(path.name)}.*-*"):
        pid = _staging_pid(leftover.name)
        if pid is not None and not psutil.pid_exists(pid):
            if leftover.is_dir() and not leftover.is_symlink():
                shutil.rmtree(leftover, ignore_errors=True)
            else:
                leftover.unlink(missing_ok=True)
