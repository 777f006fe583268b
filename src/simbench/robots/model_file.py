"""An arm's model file read into an MjSpec ready to compile: MJCF as it is, URDF through MuJoCo's own reader.
Reading a model runs no code. For a URDF:
  - every link is kept as a body (MuJoCo would fuse fixed-joint links, a UR's tool link `tool0` among them);
  - a mesh `package://NAME/rest` is read from the mapping's `packages: {NAME: folder}`, else the nearest folder
    called NAME above the URDF;
  - a mesh MuJoCo cannot decode (not STL, OBJ or MSH, e.g. COLLADA .dae) is dropped with a note where only visual
    geoms use it, and is bad input otherwise;
  - the joints' `velocity` limits are read from the file, as MuJoCo keeps none (their `effort` it keeps).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco

from simbench.robots.chain import ArmError

_PACKAGE = "package://"
_DECODED = (".stl", ".obj", ".msh")  # the mesh files MuJoCo reads


def is_urdf(path: str) -> bool:
    return path.lower().endswith(".urdf")


def read_spec(path: str, packages: tuple[tuple[str, str], ...] = ()) -> tuple[mujoco.MjSpec, tuple[str, ...]]:
    """The model at `path` (absolute) as an MjSpec ready to compile, and a note for each mesh dropped; ArmError
    naming the field at fault. `packages`: (name, absolute folder) pairs for a URDF's package:// meshes."""
    try:
        spec = mujoco.MjSpec.from_file(path)
    except ValueError as err:
        raise ArmError("model", f"MuJoCo cannot read it: {str(err).strip().splitlines()[0]}") from None
    if not is_urdf(path):
        return spec, ()
    spec.compiler.fusestatic = False
    return spec, tuple(_resolve_meshes(spec, path, dict(packages)))


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
    """Each URDF joint's (velocity, effort) limits as the file states them (SI; None where absent)."""
    limits: dict[str, tuple[float | None, float | None]] = {}
    for joint in ET.parse(path).getroot().iter("joint"):
        limit, name = joint.find("limit"), joint.get("name")
        if limit is not None and name:
            limits[name] = (_positive(limit.get("velocity")), _positive(limit.get("effort")))
    return limits


def _positive(text: str | None) -> float | None:
    """A limit's value, None where absent or not positive (URDF's 0 is 'unstated')."""
    try:
        value = float(text) if text is not None else 0.0
    except ValueError:
        return None
    return value if value > 0 else None
