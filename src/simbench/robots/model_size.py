"""A model's size, estimated from its files before MuJoCo reads them, and the refusal of what the machine cannot
hold (ArmError, exit 2) in one line: a few kilobytes of MJCF can ask for terabytes (`<replicate count="1000">`
twice makes a million bodies, and MuJoCo's collision buffers grow as the bodies squared), and MuJoCo's reading and
compiling can neither be bounded nor stopped from outside.

survey() reads the model (robots.model_xml: hardened, every number checked) and the files it includes, each of
which must be a regular file (a FIFO would block MuJoCo's read for ever), and counts what it declares, `replicate`
counts multiplied out; asset_bytes() weighs the files a read spec names (meshes, textures, height fields, skins:
regular files too, a binary STL's size its header's), checked before MuJoCo opens them. memory() is the estimate,
held to budget.machine_limits().memory (half the memory available, at most 64 GiB) by check():

    elements x ELEMENT_BYTES                     MuJoCo's spec and compiled model (measured: 5-10 kB a body)
    + arena + 4 B (B - 1)                        an MjData's arena (MuJoCo's own sizing, or <size memory>) and
                                                 the collision buffers it must hold, B bodies: what a run's data
                                                 may fill (the other MjData reserve as much but touch little)
    + mesh and other asset bytes x ASSET_FACTOR  a binary STL of 10 MB took 280 MB to compile
    + texels x TEXEL_BYTES                       textures and height fields, as declared or as a PNG's header says

fit_arena() gives the arena the collision buffers where they would not fit in it (MuJoCo's sizing leaves them out:
a few thousand bodies overflowed it, a fatal error mid-run).
"""

from __future__ import annotations

import errno
import hashlib
import math
import os
import re
import stat
import struct
from dataclasses import dataclass, field
from pathlib import Path

import mujoco

from simbench.core.budget import machine_limits
from simbench.core.budget import size as in_words
from simbench.core.errors import os_words
from simbench.robots.chain import ArmError
from simbench.robots.model_xml import check_numbers, numbers, read_xml, urdf_limits, where

ELEMENT_BYTES = 10e3  # a body, geom, joint, ... in the spec and the compiled model
ASSET_FACTOR = 30  # bytes held a byte of a mesh file (28 for binary STL, 12 for OBJ, measured)
TEXEL_BYTES = 8  # RGBA, decoded and in the model
XML_FACTOR = 40  # bytes of ElementTree a byte of XML
_CONTACT_BYTES = 584  # sizeof(mjContact)
_ARENA_SLACK = 2**20  # collision buffers below this fit in any arena MuJoCo sizes
_DOFS = {"free": (7, 6), "ball": (4, 3), "floating": (7, 6), "planar": (3, 3), "fixed": (0, 0)}  # (nq, nv)
_SUFFIX = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40, "P": 2**50, "E": 2**60}
_PNG = b"\x89PNG\r\n\x1a\n"


@dataclass
class Counts:
    """What a model declares, in MuJoCo's terms, and the files it is read from."""

    bodies: int = 1  # the world
    geoms: int = 0
    joints: int = 0
    nq: int = 0
    nv: int = 0
    sites: int = 0
    actuators: int = 0
    tendons: int = 0
    equalities: int = 0
    elements: int = 0
    texels: int = 0
    memory: int = -1  # <size memory> in bytes; -1: MuJoCo sizes the arena
    njmax: int = -1
    nconmax: int = -1
    files: list[Path] = field(default_factory=list)  # the model and what it includes: read as MuJoCo parses
    assets: list[tuple[str, str]] = field(default_factory=list)  # (tag, file) its assets name (for fingerprints)
    meshdir: str = ""  # <compiler meshdir> (or assetdir): where mesh, height field and skin files are
    texturedir: str = ""

    def joint(self, kind: str | None, times: int = 1) -> None:
        nq, nv = _DOFS.get(kind or "", (1, 1))
        self.joints += times
        self.nq += nq * times
        self.nv += nv * times

    def arena(self) -> int:
        """Bytes of each MjData's arena: <size memory>, else MuJoCo's own sizing (user_model.cc), rounded to MiB."""
        if self.memory >= 0:
            return self.memory
        njmax = 500 if self.njmax < 0 else self.njmax
        nconmax = 100 if self.nconmax < 0 else self.nconmax
        rows = njmax + self.equalities + self.nv
        base = 8 * max(1000, 5 * rows * rows + 20 * (self.nq + self.nv + self.actuators + self.bodies + self.joints
                                                      + self.geoms + self.sites + self.equalities + self.tendons))
        base += (nconmax * _CONTACT_BYTES + njmax * (8 * 4 + 14 * 8) + self.nv * 12 + njmax * self.nv * 24
                 + njmax * njmax * 12)
        return 2**20 * math.ceil(base / 2**20)

    def collision(self) -> int:
        """Bytes of the collision buffers mj_collision takes from the arena: an int per body pair, twice."""
        return 4 * self.bodies * (self.bodies - 1)


def survey(path: str) -> Counts:
    """What the MJCF or URDF at `path` declares (Counts); ArmError ('model') for a file it names that is not a
    regular file, XML simbench does not read (robots.model_xml), a number not finite, a URDF limit out of bounds,
    or a model too large for this machine before its assets are weighed."""
    problem = file_problem(Path(path))
    if problem is not None:
        raise ArmError("model", problem)
    counts = Counts()
    root = _read(Path(path), Path(path), counts)
    if root.tag == "robot":
        _urdf(root, Path(path), counts)
    else:
        _mjcf(root, Path(path), Path(path).parent, 1, counts)
    check(path, counts)
    return counts


def _read(path: Path, model: Path, counts: Counts):
    """The XML of `path` (the model or a file it includes), once its size fits the machine."""
    limit = machine_limits().memory
    bytes_ = os.stat(path).st_size * XML_FACTOR
    if bytes_ > limit:
        raise ArmError("model", f"{model.name}: reading {path.name} ({in_words(bytes_ / XML_FACTOR)} of XML) would "
                                f"need about {in_words(bytes_)} of memory, more than the {in_words(limit)} this "
                                "machine allows")
    counts.files.append(path)
    return read_xml(path)


def _mjcf(element, path: Path, folder: Path, times: int, counts: Counts, owner: str = "") -> None:
    """Count an MJCF element's children (each `times` over, replicated), reading what they include; `owner`: the
    named element they are in, in words."""
    section = element.tag
    for child in element:
        check_numbers(child, path, owner)
        tag = child.tag
        if tag == "include" or (tag == "model" and section == "asset"):
            named = child.get("file", "")
            included = folder / named
            problem = file_problem(included)
            if problem is not None:
                raise ArmError("model", f"{path.name}: {where(child)} file={named!r}: {problem}")
            if included.resolve() in {p.resolve() for p in counts.files}:  # as MuJoCo refuses it
                raise ArmError("model", f"{path.name}: {where(child)} file={named!r}: already included")
            _mjcf(_read(included, counts.files[0], counts), included, folder, times, counts, owner)
            continue
        counts.elements += times
        inner = where(child) if child.get("name") else owner
        if tag == "replicate":
            _mjcf(child, path, folder, times * _int(child, "count", 1, path), counts, inner)
            continue
        _count(section, child, times, counts, path)
        _mjcf(child, path, folder, times, counts, inner)


def _count(section: str, element, times: int, counts: Counts, path: Path) -> None:
    """Count one MJCF element (`times` over) under its parent `section`."""
    tag = element.tag
    placed = section in ("worldbody", "body", "frame", "replicate")  # not a default's, a tendon's
    if tag == "body":
        counts.bodies += times
    elif tag in ("composite", "flexcomp"):  # a grid of bodies or vertices
        counts.bodies += times * math.prod(max(0, int(n)) for n in numbers(element.get("count", "1")) or [1])
    elif tag == "geom" and placed:
        counts.geoms += times
    elif tag in ("joint", "freejoint") and placed:
        counts.joint("free" if tag == "freejoint" else element.get("type"), times)
    elif tag == "site" and placed:
        counts.sites += times
    elif section in ("actuator", "tendon", "equality"):
        attribute = {"actuator": "actuators", "tendon": "tendons", "equality": "equalities"}[section]
        setattr(counts, attribute, getattr(counts, attribute) + times)
    elif tag == "size":
        counts.memory = _memory(element.get("memory"), counts.memory)
        counts.njmax = _int(element, "njmax", counts.njmax, path)
        counts.nconmax = _int(element, "nconmax", counts.nconmax, path)
    elif tag == "texture" and element.get("builtin", "none") != "none":
        faces = 6 if element.get("type") in ("cube", "skybox") else 1
        counts.texels += times * faces * _int(element, "width", 0, path) * _int(element, "height", 0, path)
    elif tag == "hfield":
        counts.texels += times * _int(element, "nrow", 0, path) * _int(element, "ncol", 0, path)
    elif tag == "compiler":
        assetdir = element.get("assetdir")
        counts.meshdir = element.get("meshdir", assetdir if assetdir is not None else counts.meshdir)
        counts.texturedir = element.get("texturedir", assetdir if assetdir is not None else counts.texturedir)
    if section == "asset":
        counts.assets += [(tag, value) for key, value in element.attrib.items() if key.startswith("file")]


def _int(element, attribute: str, default: int, path: Path) -> int:
    """An element's count attribute (at least 0); ArmError where it is not a number."""
    text = element.get(attribute)
    try:
        return default if text is None else max(0, int(float(text)))
    except (ValueError, OverflowError):
        raise ArmError("model", f"{path.name}: {where(element)} {attribute}={text!r}: expected a whole "
                                "number") from None


def _memory(text: str | None, default: int) -> int:
    """<size memory>'s bytes ('1G', '512M', '1000')."""
    match = re.fullmatch(r"\s*(\d+)\s*([KMGTPE]?)\s*", text or "", re.IGNORECASE)
    return int(match.group(1)) * _SUFFIX[match.group(2).upper()] if match else default


def _urdf(root, path: Path, counts: Counts) -> None:
    """Count a URDF's links, joints and geoms; its limits checked (robots.model_xml.urdf_limits)."""
    owners = {child: where(parent) for parent in root.iter() if parent.get("name") for child in parent.iter()}
    for element in root.iter():
        check_numbers(element, path, owners.get(element, ""))
        counts.elements += 1
        if element.tag == "link":
            counts.bodies += 1
        elif element.tag in ("visual", "collision"):
            counts.geoms += 1
        elif element.tag == "joint" and element.get("type"):
            counts.joint({"continuous": "hinge", "revolute": "hinge"}.get(element.get("type"), element.get("type")))
        elif element.tag == "mesh" and element.get("filename"):
            counts.assets.append(("mesh", element.get("filename")))
    urdf_limits(root, path)


def memory(counts: Counts, assets: int = 0) -> tuple[float, str]:
    """Bytes loading the model would take (the module's docstring), and its largest part in words."""
    arena, collision = counts.arena(), counts.collision()
    parts = {
        f"{counts.bodies:,} bodies, {counts.geoms:,} geoms, {counts.joints:,} joints and more":
            counts.elements * ELEMENT_BYTES,
        f"MuJoCo's arena of {in_words(arena)}"
        + (" (<size memory>)" if counts.memory >= 0 else f" for {counts.nv:,} degrees of freedom"): arena,
        f"MuJoCo's collision buffers for {counts.bodies:,} bodies, which grow as the bodies squared": collision,
        f"{in_words(assets / ASSET_FACTOR)} of meshes and other assets": assets,
        f"{counts.texels:,} texels of textures and height fields": counts.texels * TEXEL_BYTES,
    }
    largest = max(parts, key=parts.__getitem__)
    return sum(parts.values()), largest


def check(path: str, counts: Counts, assets: int = 0) -> None:
    """ArmError ('model') where loading the model would take more memory than this machine allows."""
    need, largest = memory(counts, assets)
    limits = machine_limits()
    if need > limits.memory:
        basis = f" ({limits.memory_basis})" if limits.memory_basis else ""
        raise ArmError("model", f"{Path(path).name}: loading it would need about {in_words(need)} of memory (mostly "
                                f"{largest}), more than the {in_words(limits.memory)} this machine allows{basis}: "
                                "make the model smaller")


def file_problem(path: Path) -> str | None:
    """Why the file a model names cannot be read, in words, or None: it must be a regular file (a FIFO or a device
    would block the read for ever, a folder MuJoCo cannot read)."""
    text = os.fspath(path)
    if "\0" in text:
        return "expected a path without a NUL byte"
    try:
        mode = os.stat(text).st_mode
    except OSError as err:
        return f"no such file: {text}" if err.errno in (errno.ENOENT, errno.ENOTDIR) else os_words(err)
    if stat.S_ISREG(mode):
        return None
    kind = ("a folder" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode) else "a socket"
            if stat.S_ISSOCK(mode) else "a device")
    return f"not a regular file ({kind}): {text}"


def asset_bytes(spec: mujoco.MjSpec, path: str) -> int:
    """The memory the files a read spec names take (the module's docstring), each checked a regular file, a binary
    STL's size its header's; ArmError ('model') naming the asset otherwise."""
    total = 0
    for kind, items, folder in (("mesh", spec.meshes, spec.meshdir), ("hfield", spec.hfields, spec.meshdir),
                                ("skin", spec.skins, spec.meshdir), ("texture", spec.textures, spec.texturedir)):
        for item in items:
            for named in [item.file, *(getattr(item, "cubefiles", None) or [])]:
                if named:
                    total += _asset(asset_path(spec, named, folder), f"{Path(path).name}: {kind} {named!r}")
    return total


def asset_path(spec: mujoco.MjSpec, named: str, folder: str) -> Path:
    """The file MuJoCo opens for an asset's `named` file: under the model's folder and `folder` (its meshdir or
    texturedir) unless absolute, its folders stripped where the compiler says so."""
    name = Path(Path(named).name if spec.strippath else named)
    return name if name.is_absolute() else Path(spec.modelfiledir, folder, name)


def _asset(file: Path, what: str) -> int:
    """An asset file's bytes in memory (texels for a PNG)."""
    problem = file_problem(file)
    if problem is not None:
        raise ArmError("model", f"{what}: {problem}")
    length = os.stat(file).st_size
    with open(file, "rb") as handle:
        head = handle.read(84)
    if file.suffix.lower() == ".stl" and not head.lstrip().lower().startswith(b"solid") and len(head) >= 84:
        triangles = struct.unpack("<I", head[80:84])[0]
        if length != 84 + 50 * triangles:
            raise ArmError("model", f"{what}: a binary STL of {triangles:,} triangles is {84 + 50 * triangles:,} "
                                    f"bytes, this file {length:,}: expected a whole STL file")
    if head.startswith(_PNG) and len(head) >= 24:
        width, height = struct.unpack(">II", head[16:24])
        return width * height * TEXEL_BYTES
    return length * ASSET_FACTOR


def fit_arena(spec: mujoco.MjSpec, counts: Counts) -> None:
    """Make room in the spec's arena for the collision buffers of the model `counts` surveyed where they need more
    than _ARENA_SLACK (the module's docstring); an arm's model of tens of bodies is left as it is. (The counts, not
    the spec's lists: MuJoCo's spec.geoms of 12,000 geoms takes seconds.)"""
    if counts.collision() > _ARENA_SLACK:
        spec.memory = (spec.memory if spec.memory >= 0 else counts.arena()) + counts.collision()


def fingerprint(counts: Counts, assets: list[Path]) -> str:
    """A digest of the model's files by content, and of `assets` (its assets' files) by size and times of change
    (a mesh may be gigabytes): what a cache of what was derived from the model is keyed by."""
    digest = _files_digest(counts.files)
    for file in assets:
        try:
            info = os.stat(file)
        except (OSError, ValueError):  # none there: read_spec says so
            info = None
        signature = (info.st_ino, info.st_size, info.st_mtime_ns, info.st_ctime_ns) if info else None
        digest.update(f"{os.fsdecode(file)!r} {signature}".encode())
    return digest.hexdigest()[:16]


def content_fingerprint(counts: Counts, assets: list[tuple[str, Path]]) -> str:
    """A digest of the model by content alone: its files' bytes, then each asset's name as the model writes it and
    its file's bytes (`assets`: (name, file)); the same model gives the same digest on any machine, and a model
    that names no asset the digest of its files alone."""
    digest = _files_digest(counts.files)
    for named, file in assets:
        digest.update(named.encode() + b"\0")
        try:
            digest.update(_file_digest(file))
        except (OSError, ValueError):  # none there: loading the model says so
            digest.update(b"missing")
    return digest.hexdigest()[:16]


def _files_digest(files: list[Path]) -> hashlib._Hash:
    """SHA-256 over the SHA-256 digests of the files' bytes, in order."""
    digest = hashlib.sha256()
    for file in files:
        digest.update(_file_digest(file))
    return digest


def _file_digest(file: Path) -> bytes:
    """The SHA-256 digest of a file's bytes, streamed (a mesh is not held whole)."""
    with open(file, "rb") as handle:
        return hashlib.file_digest(handle, "sha256").digest()
