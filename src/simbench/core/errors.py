"""Bad input (exit 2), a run that cannot go on (exit 1), and the file system's refusals in words."""

from __future__ import annotations

import errno
import os
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from simbench.api.trajectory import JointTrajectory
    from simbench.physics.sim import Recording


class ScenarioError(Exception):
    """Bad input (exit 2): a scenario file that cannot be used.

    Attributes:
        source: The file.
        field: The field at fault, or None.
        message: What is expected.
    """

    def __init__(self, source: str, field: str | None, message: str):
        self.source = printable(source)
        self.field = None if field is None else printable(field)
        self.message = printable(message)
        super().__init__(f"{self.source}: {self.detail}")

    @property
    def detail(self) -> str:
        """The field and what is expected, without the file: what a sweep's row says of a variant."""
        return f"{self.field}: {self.message}" if self.field else self.message


def described(err: BaseException) -> str:
    """What an exception says, as `Type: message` (the type alone where it says nothing, as `sys.exit()`)."""
    return f"{type(err).__name__}: {err}" if str(err) else type(err).__name__


def printable(text: Any) -> str:
    """Text (or shown(value)) with control characters and line breaks escaped, so that an error stays one line."""
    if not isinstance(text, str):
        text = shown(text)
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)


def shown(value: Any, limit: int = 200) -> str:
    """repr(value) cut to `limit` characters; an integer too long to write out in decimal by its size, so that
    formatting an error never fails."""
    if isinstance(value, int) and not isinstance(value, bool):
        digits = int(abs(value).bit_length() * 0.30103) + 1
        if digits > MAX_INT_DIGITS:
            return f"{'-' if value < 0 else ''}an integer of about {digits} digits"
    try:
        text = repr(value)
    except ValueError:  # an integer too long inside a container, say
        return f"a {type(value).__name__} too large to show"
    return text if len(text) <= limit else f"{text[:limit - 3]}..."


# The most digits Python writes an integer out in (sys.get_int_max_str_digits; 0 means no limit).
MAX_INT_DIGITS = sys.get_int_max_str_digits() or 4300


class RunError(Exception):
    """A valid scenario whose run failed (exit 1): an unreachable path, diverged physics."""


class TooSlow(RunError):
    """A run cut where it passed a time limit it was given (a bench's plan_seconds): a sweep's or bench's row
    `too_slow`."""


class PhysicsError(RunError):
    """The simulation failed mid-run.

    Attributes:
        t: When (s); negative while settling at the start pose.
        cause: Why, in words.
        trajectory: The plan.
        recording: The recording so far; None while settling.
    """

    failed = "physics failed"

    def __init__(self, t: float, cause: str, trajectory: JointTrajectory, recording: Recording | None):
        self.t = t
        self.cause = cause
        self.trajectory = trajectory
        self.recording = recording
        when = f"at t = {t:.4f} s" if t >= 0 else f"while settling at the start pose ({-t:.4f} s before the start)"
        super().__init__(f"{self.failed} {when}: {cause}")


class ControlError(PhysicsError):
    """A controller failed mid-run (it raised, or commanded NaN or the wrong shape): as PhysicsError."""

    failed = "control failed"


class OutputError(RunError):
    """Writing outputs failed (a full disk, say).

    Attributes:
        path: The file that could not be written.
        problem: The file system's words.
        kept: What was kept of the outputs.
    """

    def __init__(self, path: str, problem: str, kept: str):
        self.path = printable(path)
        self.problem = problem
        self.kept = kept
        super().__init__(f"{self.path}: {problem} (while writing the outputs; {kept})")


# --- the file system's refusals in words ------------------------------------------------------------------------

# The machine ran out, rather than the user picking a bad place: a run failure (exit 1) wherever met.
NO_SPACE = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT})

# Where os.strerror's words would mislead or say too little.
_WORDS = {
    errno.ENOSPC: "no space left on the device",
    errno.EFBIG: "no space for a file this large: over the file system's or this process's file-size limit",
    errno.EDQUOT: "no space left: disk quota exceeded",
    errno.ELOOP: "a symlink loop (too many levels of symbolic links)",
    errno.EXDEV: "on another file system",
}

# The hidden names simbench writes under beside a destination (simbench.core.atomic, simbench.core.destination).
STAGED = re.compile(r"^\.(?P<name>.+)\.(?:partial|old)-(?P<pid>\d+)$")
_LOCK = re.compile(r"^\.(?P<name>.+)\.lock$")
_ERRNO_IN_TEXT = re.compile(r"^\[Errno (\d+)\] ([^\n]*)")


def shown_path(filename: str | os.PathLike | bytes | None) -> str | None:
    """The path the user knows: a staged name (`.report.json.partial-PID`) as its final one, a lock as its folder."""
    if filename is None:
        return None
    path = Path(os.fsdecode(filename))
    if _LOCK.match(path.name):
        return str(path.parent)
    parts = [(m.group("name") if (m := STAGED.match(part)) else part) for part in path.parts]
    return str(Path(*parts)) if parts else str(path)


def nearest_folder(path: str | os.PathLike) -> Path:
    """The nearest folder that exists at or above `path`."""
    path = Path(os.path.abspath(path))
    return next((p for p in (path, *path.parents) if os.path.isdir(p)), Path(path.anchor))


def name_max(folder: str | os.PathLike) -> int:
    """The longest file name (bytes) the file system holding `folder` (or its nearest ancestor) takes."""
    try:
        return os.pathconf(nearest_folder(folder), "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def _too_long(filename: str) -> str:
    """ENAMETOOLONG in words: which name, how long, and the limit."""
    path = Path(filename)
    limit = name_max(path.parent)
    for part in path.parts:
        length = len(os.fsencode(part))
        if length > limit:
            return f"name too long ({length} characters; at most {limit})"
    length = len(os.fsencode(filename))
    try:
        limit = os.pathconf(Path(os.path.abspath(filename)).anchor, "PC_PATH_MAX")
    except (OSError, ValueError):
        limit = 4096
    return f"path too long ({length} characters; at most {limit})"


def _file_in_the_way(filename: str) -> str | None:
    """The first component of `filename` that exists and is not a folder (ENOTDIR, or EEXIST of a mkdir)."""
    path = Path(filename)
    for candidate in (*reversed(path.parents), path):
        try:
            if candidate.exists() and not candidate.is_dir():
                return str(candidate)
        except OSError:
            return None
    return None


def os_words(err: OSError) -> str:
    """What the file system refused, in words, naming the file in the way or the lengths where that helps."""
    code, filename = err.errno, err.filename
    text = (err.strerror or str(err) or "").strip()
    if code is None and (m := _ERRNO_IN_TEXT.match(text)):  # an OSError made of another's text (imageio's)
        code, text = int(m.group(1)), m.group(2)
    name = None if filename is None else os.fsdecode(filename)
    if code in (errno.ENOTDIR, errno.EEXIST) and name is not None:
        blocker = _file_in_the_way(name)
        if blocker is not None:
            return f"{printable(shown_path(blocker))} is a file, not a folder"
        if code == errno.ENOTDIR:
            return "a file where a folder was expected"
        return "already exists"
    if code == errno.ENAMETOOLONG:
        return _too_long(name) if name is not None else "name too long"
    if code in _WORDS:
        return _WORDS[code]
    if code is not None:
        text = os.strerror(code)
    return printable(text.splitlines()[0] if text else type(err).__name__).lower()


def os_error_line(err: OSError) -> tuple[str | None, str]:
    """(the path an OSError is about, as the user knows it; what went wrong in words)."""
    return printable(shown_path(err.filename)) if err.filename is not None else None, os_words(err)


def destination_error(out: Path, err: OSError) -> Exception:
    """A destination refused before anything ran: ScenarioError naming `out`, or OutputError if out of space."""
    path, words = os_error_line(err)
    if err.errno in NO_SPACE:
        return OutputError(path or str(out), words, f"{out} was left as it was")
    where = f" ({path})" if path and path != str(out) and err.errno not in (errno.ENOTDIR, errno.EEXIST) else ""
    return ScenarioError(str(out), None, f"cannot write the output folder: {words}{where}; pick another --out")


def output_error(err: OSError, path: Path, kept: str) -> OutputError:
    """OutputError for an OSError met while writing outputs into `path`."""
    where, words = os_error_line(err)
    if err.errno in (None, errno.EPIPE, errno.EIO) and _device_full(path):  # a writer that lost the cause: a
        words = f"no space left on the device ({words})"  # pipe to ffmpeg broken by ffmpeg's own ENOSPC, say
    return OutputError(where or str(shown_path(path)), words, kept)


def _device_full(path: Path) -> bool:
    """Whether the file system holding `path` (or its nearest ancestor) has no block left."""
    try:
        return os.statvfs(nearest_folder(path)).f_bavail == 0
    except OSError:
        return False


class RegistryError(Exception):
    """A plugin that cannot be registered (a name taken, the wrong type, a broken entry point)."""
