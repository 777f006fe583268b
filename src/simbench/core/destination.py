"""Where a run or a sweep writes: never over anything simbench did not write, one writer at a time, nothing left
behind by a writer that was killed.

Every folder simbench writes holds a marker, `.simbench`, of JSON lines listing the files (and empty folders)
written there by relative path (a sweep appends a line before each batch); `--force` replaces a folder only if
markers account for everything in it. A lock file beside the folder (`.<name>.lock`, an flock the kernel drops
when its holder dies, holding simbench's token) keeps a second writer out.

What a writer killed midway leaves is removed only where it is provably simbench's (`leftover`): a staging or
set-aside folder (`.<name>.partial-PID`, `.<name>.old-PID`) of a process that is gone and that holds a simbench
marker (written as the folder is made, removed last), a staged file of such a process whose final name a marker
lists, or a lock file holding the token that no process holds. A file of the user's that only looks like one
(`.thesis.old-1/`, an empty `.keep.lock`) is theirs: a write it is in the way of is refused, naming it.
"""

from __future__ import annotations

import errno
import glob
import json
import os
import shutil
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, suppress
from contextvars import ContextVar
from pathlib import Path

import psutil
from filelock import FileLock, Timeout

from simbench.core.errors import STAGED, ScenarioError, destination_error, name_max

MARKER = ".simbench"
# The longest suffix this process writes under beside a destination: `.<name>.partial-<pid>` (simbench.core.atomic).
_HIDDEN = len(".") + len(".partial-") + len(str(2**22))
# What simbench writes into a lock file it holds, so that one its killed holder left can be told from a user's.
LOCK_TOKEN = b"simbench lock\n"
# Whether refusals speak to the command line (`--force`) or to a Python caller (`force=True`): command_line().
_COMMAND_LINE: ContextVar[bool] = ContextVar("simbench_command_line", default=False)


@contextmanager
def command_line() -> Iterator[None]:
    """Within the block, refusals name the command line's options (`--force`, `--out`) rather than the Python
    API's arguments (`force=True`, `out`): the CLI runs each command in it."""
    token = _COMMAND_LINE.set(True)
    try:
        yield
    finally:
        _COMMAND_LINE.reset(token)


def option(flag: str, argument: str) -> str:
    """`flag` (`--force`) within command_line(), else `argument` (`force=True`): what a refusal tells to pass."""
    return flag if _COMMAND_LINE.get() else argument


@contextmanager
def refused(out: Path) -> Iterator[None]:
    """An OSError met while looking at or preparing `out` as errors.destination_error."""
    try:
        yield
    except OSError as err:
        raise destination_error(out, err) from None


def mark(folder: Path, names: Iterable[str] | None = None) -> None:
    """Write the marker of a folder simbench wrote: `names`, or every file and empty folder (`name/`) now in it."""
    if names is None:
        names = sorted(_shown(p, folder) for p in folder.rglob("*") if p != folder / MARKER and (
            p.is_file() or (_is_folder(p) and not any(p.iterdir()))))
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


def _lines(folder: Path) -> Iterator[dict]:
    """The lines of the marker of `folder` as JSON objects (none if it is not a file; unreadable lines skipped)."""
    marker = folder / MARKER
    try:
        text = marker.read_text() if marker.is_file() and not marker.is_symlink() else ""
    except (OSError, UnicodeDecodeError):
        return
    for line in text.splitlines():
        with suppress(ValueError):
            if isinstance(entry := json.loads(line), dict):
                yield entry


def _listed(folder: Path) -> set[str]:
    """The paths the marker of `folder` lists."""
    names: set[str] = set()
    for entry in _lines(folder):
        if isinstance(files := entry.get("files"), list):
            names.update(name for name in files if isinstance(name, str))
    return names


def marked(folder: Path) -> bool:
    """Whether `folder` holds a marker simbench wrote (its first line says so)."""
    return next(_lines(folder), {}).get("written_by") == "simbench"


def _accounts(names: set[str], path: str, folder: bool) -> bool:
    """Whether `names` (a marker's) account for `path` (relative to the marker's folder): listed, or for a folder
    listed as `path/` or holding a listed path."""
    return path in names or folder and (f"{path}/" in names or any(n.startswith(f"{path}/") for n in names))


def foreign(folder: Path, empty: bool = False) -> list[Path]:
    """What is in `folder`, at every depth, that no marker on the way down accounts for: files and symlinks, and
    with `empty` empty folders; simbench's own leftovers (`leftover`) excepted."""
    listed: dict[Path, set[str]] = {}
    out = []
    for path in _contents(folder, empty):
        owners = [path.parent, *(p for p in path.parent.parents if folder in p.parents or p == folder)]
        if not any(_accounts(listed.setdefault(owner, _listed(owner)), path.relative_to(owner).as_posix(),
                             _is_folder(path)) for owner in owners):
            out.append(path)
    return out


def _contents(folder: Path, empty: bool) -> Iterator[Path]:
    """The files and symlinks in `folder`, at every depth and in name order, and with `empty` its empty folders;
    but its markers and simbench's leftovers (whose contents are not looked into)."""
    for path in sorted(folder.iterdir()):
        if (path.name == MARKER and path.is_file() and not path.is_symlink()) or leftover(path):
            continue
        if not _is_folder(path):
            yield path
        elif any(path.iterdir()):
            yield from _contents(path, empty)
        elif empty:
            yield path


def _is_folder(path: Path) -> bool:
    return path.is_dir() and not path.is_symlink()


def _shown(path: Path, folder: Path) -> str:
    """`path` relative to `folder`, a folder's with a trailing `/`."""
    return path.relative_to(folder).as_posix() + ("/" if _is_folder(path) else "")


def leftover(path: Path) -> bool:
    """Whether `path` is what a simbench writer that is gone left behind, so that removing it loses nothing of the
    user's: a staging or set-aside folder (`.<name>.partial-PID`, `.<name>.old-PID`) that holds a simbench marker,
    or a staged file whose final name a marker on the way up lists, of a process that no longer runs; or a lock
    file (`.<name>.lock`) that holds simbench's token and that no process holds. A name alone proves nothing."""
    try:
        if path.is_symlink():
            return False
        if (m := STAGED.match(path.name)) is not None:
            if psutil.pid_exists(int(m["pid"])):
                return False
            return marked(path) if path.is_dir() else path.is_file() and _claimed(path.with_name(m["name"]))
        return path.name.startswith(".") and path.name.endswith(".lock") and path.is_file() and _stale_lock(path)
    except OSError:
        return False


def _claimed(path: Path) -> bool:
    """Whether a marker in a folder above `path` lists it."""
    path = path.absolute()
    return any(path.relative_to(owner).as_posix() in _listed(owner) for owner in path.parents)


def _stale_lock(path: Path) -> bool:
    """Whether `path` holds simbench's lock token and no process holds its lock (False where that cannot be told:
    a platform without flock)."""
    signed, held = _lock_state(path)
    return signed and held is False


def _lock_state(path: Path) -> tuple[bool, bool | None]:
    """Whether the file at `path` holds simbench's lock token, and whether a process holds a lock on it (None
    where that cannot be told: a platform without flock)."""
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    try:
        signed = os.read(fd, len(LOCK_TOKEN)) == LOCK_TOKEN
        try:
            import fcntl
        except ImportError:
            return signed, None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)  # released as fd is closed
        except OSError:
            return signed, True
        return signed, False
    finally:
        os.close(fd)


def remove(path: Path) -> None:
    """Remove a folder or file of simbench's, as far as it can be; a folder's marker last, so that what a writer
    stopped midway leaves is still known as simbench's."""
    if not _is_folder(path):
        with suppress(OSError):
            path.unlink(missing_ok=True)
        return
    with suppress(OSError):
        for entry in path.iterdir():
            if entry.name != MARKER:
                if _is_folder(entry):
                    shutil.rmtree(entry, ignore_errors=True)
                else:
                    with suppress(OSError):
                        entry.unlink()
    with suppress(OSError):
        (path / MARKER).unlink(missing_ok=True)
        path.rmdir()


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


def check_replace(out: Path, why: str | None = None, removes: bool = False) -> None:
    """ScenarioError naming one stranger unless simbench wrote everything in `out`. `removes`: the caller then
    removes `out` whole (replaces it), so that an empty folder no marker accounts for is a stranger too (one that
    writes into `out`, a resumed sweep, leaves such a folder alone). `why`: what the refusal says replaces only
    simbench's outputs (default: `--force`, or `force=True` from Python)."""
    why = why or f"{option('--force', 'force=True')} replaces only simbench's own outputs"
    with refused(out):
        strangers = foreign(out, removes)
        unmarked = None if strangers or (out / MARKER).is_file() else next(_contents(out, removes), None)
    if strangers:
        raise ScenarioError(str(out), None, f"holds {len(strangers)} file(s) or folder(s) simbench did not write "
                                            f"(such as {_shown(strangers[0], out)}); {why}: move them out yourself "
                                            "or pick another --out")
    if unmarked is not None:  # outputs of other runs in its subfolders (renders/ itself, say): not one output
        raise ScenarioError(str(out), None, f"holds other runs' outputs (such as {_shown(unmarked, out)}) and is "
                                            f"not itself a folder simbench wrote (no {MARKER} of its own); {why}: "
                                            "pick another --out")


def check(out: Path, inputs: Iterable[Path], force: bool) -> None:
    """ScenarioError unless outputs may go to `out`: a non-empty folder only with `force` and check_replace."""
    check_inputs(out, inputs)
    with refused(out):
        holds = out.is_dir() and any(out.iterdir())
    if holds:
        if not force:
            raise ScenarioError(str(out), None, f"the output folder exists; pass {option('--force', 'force=True')} to "
                                                f"replace it, or {option('--out', 'another out')} to write elsewhere")
        check_replace(out, removes=True)


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
            _refuse_a_strangers_lock(path, out)
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


def _refuse_a_strangers_lock(path: Path, out: Path) -> None:
    """ScenarioError where a file simbench did not write sits where it keeps the lock of `out`: one neither signed
    with its token nor held by a writer (which may not have signed it yet) is the user's, even empty (the module's
    docstring), and the lock, removed when the write ends, would take it with it."""
    if path.is_symlink() or not path.is_file():
        return  # (none; or a symlink or folder: _take refuses it)
    signed, held = _lock_state(path)
    if not (signed or held):
        raise ScenarioError(str(path), None, f"is a file simbench did not write, where it keeps the lock of "
                                             f"{out.name}: move it, or pass --out to write elsewhere")


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
    _sign(path)
    return lock


def _sign(path: Path) -> None:
    """Write LOCK_TOKEN into the lock file at `path`, held by this process and empty (filelock's own fallback on
    a file system without flock writes there first: kept), so that a holder killed leaves a lock known as
    simbench's. Where it cannot be written the lock still holds; a leftover of it is then never removed."""
    with suppress(OSError):
        fd = os.open(path, os.O_WRONLY | os.O_NOFOLLOW)
        try:
            if os.fstat(fd).st_size == 0:
                os.write(fd, LOCK_TOKEN)
        finally:
            os.close(fd)


def check_name(out: Path) -> None:
    """ScenarioError if the name of `out` is too long for the staging names written beside it."""
    length, limit = len(os.fsencode(out.name)), name_max(out.parent) - _HIDDEN
    if length > limit:
        raise ScenarioError(str(out), None, f"name too long ({length} characters; at most {limit} for an output "
                                            "folder, which simbench first writes under a longer hidden name); pick "
                                            "another --out")


def sweep_leftovers(path: Path) -> None:
    """Remove simbench's leftovers (`leftover`) under the staging names beside `path`: a writer's killed by
    SIGKILL, say."""
    for candidate in path.parent.glob(f".{glob.escape(path.name)}.*-*"):
        if STAGED.match(candidate.name) and leftover(candidate):
            remove(candidate)
