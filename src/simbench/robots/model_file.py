"""An arm's model file read into an MjSpec ready to compile: MJCF as it is, URDF through MuJoCo's own reader.
Reading a model runs no code, and nothing MuJoCo cannot be stopped in starts before simbench has read the files:
  - the model is surveyed first (robots.model_size: hardened XML, every number finite, every file it includes or
    names a regular file, its size held to the machine's memory) and refused in one line (ArmError);
  - MuJoCo reads and compiles it on a thread this one waits for (`interruptible`), so that Ctrl-C and SIGTERM are
    answered at once, and MuJoCo's warnings are kept from the terminal and from a MUJOCO_LOG.TXT;
  - the arena is given room for MuJoCo's collision buffers where a model of many bodies needs it.
For a URDF:
  - every link is kept as a body (MuJoCo would fuse fixed-joint links, a UR's tool link `tool0` among them);
  - a mesh `package://NAME/rest` is read from the mapping's `packages: {NAME: folder}`, else the nearest folder
    called NAME above the URDF;
  - a mesh MuJoCo cannot decode (not STL, OBJ or MSH, e.g. COLLADA .dae) is dropped with a note where only visual
    geoms use it, and is bad input otherwise;
  - the joints' `velocity` limits are read from the file, as MuJoCo keeps none (their `effort` it keeps), each
    limit checked (robots.model_xml.urdf_limits).
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco

from simbench.core.faults import quiet_mujoco
from simbench.robots import model_size
from simbench.robots.chain import ArmError
from simbench.robots.model_xml import read_xml
from simbench.robots.model_xml import urdf_limits as _stated_limits

_PACKAGE = "package://"
_DECODED = (".stl", ".obj", ".msh")  # the mesh files MuJoCo reads


def is_urdf(path: str) -> bool:
    return path.lower().endswith(".urdf")


def read_spec(path: str, packages: tuple[tuple[str, str], ...] = ()) -> tuple[mujoco.MjSpec, tuple[str, ...]]:
    """The model at `path` (absolute) as an MjSpec ready to compile, and a note for each mesh dropped; ArmError
    naming the field at fault. `packages`: (name, absolute folder) pairs for a URDF's package:// meshes."""
    counts = model_size.survey(path)
    try:
        spec = interruptible(mujoco.MjSpec.from_file, path)
    except ValueError as err:
        raise ArmError("model", f"MuJoCo cannot read it: {mujoco_words(err)}") from None
    notes: tuple[str, ...] = ()
    if is_urdf(path):
        spec.compiler.fusestatic = False
        notes = tuple(_resolve_meshes(spec, path, dict(packages)))
    model_size.check(path, counts, model_size.asset_bytes(spec, path))
    model_size.fit_arena(spec, counts)
    return spec, notes


def compiled(spec: mujoco.MjSpec) -> mujoco.MjModel:
    """spec.compile(), interruptible; ArmError ('model') where MuJoCo cannot compile it."""
    try:
        return interruptible(spec.compile)
    except ValueError as err:
        raise ArmError("model", f"MuJoCo cannot load it: {mujoco_words(err)}") from None


def mujoco_words(err: Exception) -> str:
    """MuJoCo's error, whole, on one line (its first line may end at a colon: 'XML parse error 8:')."""
    return " ".join(line.strip() for line in str(err).strip().splitlines() if line.strip())


def interruptible(fn: Callable[..., Any], *args: Any) -> Any:
    """fn(*args) run on a thread that this one waits for, MuJoCo's warnings silenced: MuJoCo lets go of the GIL
    while it reads and compiles, so that a signal's handler (interrupts.raising_interrupted) runs here at once
    instead of when MuJoCo is done. An interrupted call's thread ends with the process."""
    outcome: dict[str, Any] = {}

    def call() -> None:
        try:
            outcome["value"] = fn(*args)
        except BaseException as err:  # noqa: BLE001  raised again in the caller's thread
            outcome["error"] = err

    with quiet_mujoco(), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the compiler's warnings (a near-singular inertia): not the user's lines
        thread = threading.Thread(target=call, name="simbench-model", daemon=True)
        thread.start()
        thread.join()
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


def _resolve_meshes(spec: mujoco.MjSpec, path: str, packages: dict[str, str]) -> list[str]:
    """Each mesh's package:// file made a path; meshes MuJoCo cannot decode dropped where visual only (notes)."""
    notes = []
    for mesh in list(spec.meshes):
        named = mesh.file
        if named.startswith(_PACKAGE):
            mesh.file = str(_package_folder(named, path, packages) / named[len(_PACKAGE):].partition("/")[2])
        if Path(mesh.file).suffix.lower() in _DECODED:
            continue
        users = [geom for geom in spec.geoms if geom.meshname == mesh.name]
        if any(geom.contype or geom.conaffinity for geom in users):
            raise ArmError("model", f"mesh {named} of {Path(path).name}: MuJoCo cannot decode "
                                    f"{Path(mesh.file).suffix or 'it'} meshes and a colliding geom uses it: "
                                    "convert it to STL or OBJ (e.g. with meshlab or trimesh) and name that file")
        for geom in users:
            spec.delete(geom)
        spec.delete(mesh)
        notes.append(f"visual mesh {named} dropped: MuJoCo cannot decode {Path(named).suffix} (convert it to STL "
                     "or OBJ to see it)")
    return notes


def _package_folder(named: str, path: str, packages: dict[str, str]) -> Path:
    """The folder of a package:// URI's package (the module's docstring)."""
    name = named[len(_PACKAGE):].partition("/")[0]
    if name in packages:
        return Path(packages[name])
    for folder in Path(path).parents:
        if folder.name == name:
            return folder
    raise ArmError("packages", f"mesh {named} of {Path(path).name}: no folder '{name}' above the URDF; give it, "
                               f"packages: {{{name}: FOLDER}}")


def urdf_limits(path: str) -> dict[str, tuple[float | None, float | None]]:
    """Each URDF joint's (velocity, effort) limits as the file states them (SI; None where absent or 0)."""
    return _stated_limits(read_xml(Path(path)), Path(path))


def fingerprint(path: str, packages: tuple[tuple[str, str], ...] = ()) -> str:
    """A digest of the model's files by content (its own, those it includes) and of the files its assets name by
    their size and times of change; robots.model_size.fingerprint."""
    counts = model_size.survey(path)
    return model_size.fingerprint(counts, [file for _, file in _asset_files(path, counts, dict(packages))])


def content_hash(path: str, packages: dict[str, str] | None = None) -> str:
    """A digest of the model by content alone, the files its assets name included (meshes, textures, height
    fields): the same on any machine for the same files; robots.model_size.content_fingerprint."""
    counts = model_size.survey(path)
    return model_size.content_fingerprint(counts, _asset_files(path, counts, packages or {}))


def _asset_files(path: str, counts: model_size.Counts, packages: dict[str, str]) -> list[tuple[str, Path]]:
    """Each file the model's assets name, as the model names it and where read_spec finds it: beside the model
    under its meshdir or texturedir, or a URDF's package:// mesh in its package's folder (one not found is left
    out: read_spec says so)."""
    folder, found = Path(path).parent, []
    for tag, named in counts.assets:
        if not named.startswith(_PACKAGE):
            found.append((named, Path(folder, counts.texturedir if tag == "texture" else counts.meshdir, named)))
            continue
        try:
            found.append((named, _package_folder(named, path, packages) / named[len(_PACKAGE):].partition("/")[2]))
        except ArmError:
            continue
    return found
