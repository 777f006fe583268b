"""A model file's XML read as simbench reads it before MuJoCo does: hardened, and every number it states checked.

MuJoCo's own reader is lenient where simbench's must not be: simbench reads no document type declaration (a DTD's
entities could expand without bound, or name a file outside the model), refuses a file that is not well-formed
XML (a bare `&`), and refuses a number that is not finite ('nan', 'inf', '1e400') wherever the file states one,
and a length, angle, mass or inertia beyond MAX_MAGNITUDE, naming the element and the attribute: MuJoCo would
compile such a number into an arm that moves nowhere (a NaN range makes a joint continuous, a NaN effort no force
limit). A URDF's joint limits are checked too (urdf_limits): ordered, and its `velocity` and `effort` within the
bounds a robot mapping allows its own `speed_limits` and `force_limits`.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from xml.parsers import expat

from simbench.robots.chain import ArmError

MAX_MAGNITUDE = 1e6  # m, kg, kg m^2, deg or rad: far past any manipulator, well inside MuJoCo's 1e10 "huge value"
MAX_DEPTH = 500  # elements nested (tinyxml2's, MuJoCo's reader's, bound)
MAX_LIMIT = 1e6  # a URDF joint's velocity (rad/s, m/s) and effort (N m, N): robot_mapping's own bounds

# Attributes whose value is a name or a word, never a number (a body may be called "inf").
_WORDS = {"name", "class", "childclass", "type", "mesh", "material", "texture", "hfield", "skin", "joint", "joint1",
          "joint2", "body", "body1", "body2", "site", "site1", "site2", "geom", "geom1", "geom2", "tendon",
          "actuator", "objname", "refname", "objtype", "reftype", "target", "prefix", "suffix", "link", "model",
          "content_type", "builtin", "mark", "key", "plugin", "instance", "cranksite", "slidersite", "jointinparent",
          "mode", "version", "meshdir", "texturedir", "assetdir", "angle", "coordinate", "eulerseq", "inertia",
          "user", "data", "string", "text"}
# Attributes of length, angle, mass or inertia, held to MAX_MAGNITUDE (MJCF's and URDF's names).
_GEOMETRIC = {"pos", "xyz", "rpy", "quat", "axis", "euler", "axisangle", "xyaxes", "zaxis", "fromto", "size",
              "mass", "diaginertia", "fullinertia", "radius", "length", "scale", "ixx", "ixy", "ixz", "iyy", "iyz",
              "izz", "ipos", "iquat"}


def read_xml(path: Path) -> ET.Element:
    """The XML file at `path` as a tree, read without a DTD or entities; ArmError ('model') where it has a DOCTYPE
    or is not well-formed. A character reference XML forbids (&#27;, ESC), which MuJoCo reads into a name, reads
    as '?': names are not what this reading is for."""
    builder = ET.TreeBuilder()
    parser = expat.ParserCreate()
    depth = [0]

    def start(tag: str, attributes: dict[str, str]) -> None:
        depth[0] += 1
        if depth[0] > MAX_DEPTH:
            raise ArmError("model", f"{path.name} line {parser.CurrentLineNumber}: elements nested more than "
                                    f"{MAX_DEPTH} deep (MuJoCo's XML reader reads none deeper)")
        builder.start(tag, attributes)

    def end(tag: str) -> None:
        depth[0] -= 1
        builder.end(tag)

    parser.StartElementHandler = start
    parser.EndElementHandler = end

    def doctype(*_) -> None:
        raise ArmError("model", f"{path.name} line {parser.CurrentLineNumber}: a document type declaration "
                                "(<!DOCTYPE ...>): simbench reads no DTD or entities (they could expand without "
                                "bound or name other files); remove it")

    parser.StartDoctypeDeclHandler = doctype
    try:
        parser.Parse(_CHARACTER.sub(_allowed, path.read_bytes()), True)
    except expat.ExpatError as err:
        raise ArmError("model", f"{path.name}: not well-formed XML: {expat.errors.messages[err.code]} (line "
                                f"{err.lineno}, column {err.offset + 1})") from None
    return builder.close()


_CHARACTER = re.compile(rb"&#(x[0-9a-fA-F]+|[0-9]+);")


def _allowed(match: re.Match) -> bytes:
    """A character reference kept where XML 1.0 allows its character, else '?'."""
    text = match.group(1).decode()
    code = int(text[1:], 16) if text.startswith("x") else int(text)
    ok = code in (0x9, 0xA, 0xD) or 0x20 <= code <= 0xD7FF or 0xE000 <= code <= 0xFFFD or 0x10000 <= code <= 0x10FFFF
    return match.group(0) if ok else b"?"


def check_numbers(element: ET.Element, path: Path, owner: str = "") -> None:
    """ArmError ('model') for the first number of `element` (one element, not its children) that is not finite, or
    a length, angle, mass or inertia beyond MAX_MAGNITUDE; `owner`: the named element it is in, in words."""
    for attribute, text in element.attrib.items():
        values = None if attribute in _WORDS or attribute.startswith("file") else numbers(text)
        if values is None:
            continue
        problem = "expected finite numbers" if not all(map(math.isfinite, values)) else None
        if problem is None and (attribute in _GEOMETRIC or (element.tag, attribute) == ("mass", "value")):
            problem = (f"expected numbers of at most {MAX_MAGNITUDE:g} in magnitude"
                       if max(map(abs, values), default=0.0) > MAX_MAGNITUDE else None)
        if problem is not None:
            within = f"{owner} " if owner and element.get("name") is None else ""
            raise ArmError("model", f"{path.name}: {within}{where(element)} {attribute}={text.strip()!r}: {problem}")


def numbers(text: str) -> list[float] | None:
    """The numbers an attribute's text holds, or None where it is not a list of numbers."""
    try:
        return [float(token) for token in text.split()]
    except ValueError:
        return None


def where(element: ET.Element) -> str:
    """An element as a reader finds it in the file: <tag name="...">."""
    name = element.get("name")
    return f"<{element.tag} name={name!r}>" if name else f"<{element.tag}>"


def urdf_limits(root: ET.Element, path: Path) -> dict[str, tuple[float | None, float | None]]:
    """Each URDF joint's (velocity, effort) limits as the file states them (SI; None where absent or 0, URDF's
    'unstated'); ArmError ('model') for a limit that is not a number in [0, MAX_LIMIT], or a `lower` above the
    `upper`."""
    limits: dict[str, tuple[float | None, float | None]] = {}
    for joint in root.iter("joint"):
        limit, name = joint.find("limit"), joint.get("name")
        if limit is None or not name:
            continue
        lower, upper = (_limit(limit, joint, path, bound, None) for bound in ("lower", "upper"))
        if lower is not None and upper is not None and lower > upper:
            raise ArmError("model", f"{path.name}: joint {name!r} <limit>: lower {lower:g} is above upper {upper:g}: "
                                    "expected lower <= upper")
        velocity, effort = (_limit(limit, joint, path, kind, MAX_LIMIT) or None for kind in ("velocity", "effort"))
        limits[name] = velocity, effort
    return limits


def _limit(limit: ET.Element, joint: ET.Element, path: Path, attribute: str, bound: float | None) -> float | None:
    """A <limit>'s attribute, None where absent; ArmError where it is not a finite number (in [0, bound])."""
    text = limit.get(attribute)
    if text is None:
        return None
    values = numbers(text)
    value = values[0] if values is not None and len(values) == 1 else math.nan
    if math.isfinite(value) and (bound is None or 0 <= value <= bound):
        return value
    expected = "a finite number" if bound is None else f"a number from 0 to {bound:g}"
    raise ArmError("model", f"{path.name}: joint {joint.get('name')!r} <limit {attribute}>: expected {expected}, "
                            f"got {text.strip()!r}")
