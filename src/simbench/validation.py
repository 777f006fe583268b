"""Reading YAML input and turning pydantic's validation errors into one line naming the field.

Shared by scenario files and sweep files, so both fail the same way: the file, the field as the user wrote it
(`task.goal[1]`), and what is expected.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from simbench.errors import ScenarioError

_MAX_BYTES = 1 << 20


def read_yaml(path: Path) -> Any:
    """The YAML document in `path`; ScenarioError if it is missing, too large, not text, not YAML or empty."""
    source = str(path)
    if not path.exists():
        raise ScenarioError(source, None, "no such file")
    if not path.is_file():
        raise ScenarioError(source, None, "not a file (expected a YAML scenario)")
    size = path.stat().st_size
    if size > _MAX_BYTES:
        raise ScenarioError(source, None, f"file too large ({size} bytes; a scenario is at most {_MAX_BYTES})")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        raise ScenarioError(source, None, "not a text file (expected UTF-8 YAML)") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise ScenarioError(source, None, f"not valid YAML{where}: {problem}") from None
    if data is None:
        raise ScenarioError(source, None, "empty file: expected a mapping of scenario fields")
    return data


def kind_of(value: Any) -> str:
    return {list: "a list", str: "a string", int: "a number", float: "a number", bool: "a boolean"}.get(
        type(value), f"a {type(value).__name__}")


def format_loc(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _fields_at(cls: type[BaseModel], loc: tuple) -> list[str]:
    """Field names of the model found by following loc from cls (for 'did you mean')."""
    model = cls
    for part in loc:
        field = model.model_fields.get(part) if isinstance(part, str) else None
        annotation = getattr(field, "annotation", None)
        if not (isinstance(annotation, type) and issubclass(annotation, BaseModel)):
            return []
        model = annotation
    return list(model.model_fields)


def _field_loc(loc) -> tuple:
    """A pydantic error location without the names it gives the members of a union (float, list[float],
    function-after[...], a model's class name): only the field names and list indices the user wrote."""
    return tuple(p for p in loc if not (isinstance(p, str) and (p in ("float", "int", "str", "bool") or "[" in p
                                                                 or p[:1].isupper())))


def _reads_as_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def describe(err: ValidationError, cls: type[BaseModel], prefix: tuple = ()) -> tuple[str, str]:
    """The first validation error as (field path, message in the user's terms).

    An unknown field goes first: a misspelt name also makes the field it meant go missing.
    """
    errors = err.errors(include_url=False)
    first = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
    loc = prefix + _field_loc(first["loc"])
    kind, msg, given = first["type"], first["msg"], first.get("input")
    # A value that fits no member of a union (a number or a list) fails once per member: say what each expects.
    alike = [e["msg"] for e in errors if _field_loc(e["loc"]) == _field_loc(first["loc"])
             and e["msg"].startswith("Input should be") and e is not first]
    if alike and msg.startswith("Input should be"):
        msg = " or ".join([msg] + [m.removeprefix("Input should be ") for m in alike])
    if kind == "missing":
        return format_loc(loc), "missing: this field is required"
    if kind == "extra_forbidden":
        fields = _fields_at(cls, tuple(first["loc"])[:-1])
        hint = difflib.get_close_matches(str(loc[-1]), fields, n=1)
        suggestion = f"; did you mean '{hint[0]}'?" if hint else ""
        return format_loc(loc), f"unknown field (expected one of: {', '.join(fields)}){suggestion}"
    if msg.startswith("Value error, "):
        return format_loc(loc), msg.removeprefix("Value error, ")
    msg = msg.replace("Input should be", "expected").replace("String should", "expected a string to")
    if isinstance(given, (str, int, float, bool)) or given is None:
        msg += f", got {given!r}"
        if isinstance(given, str) and _reads_as_number(given):
            msg += f" (YAML reads {given} as text: write it with a decimal point, e.g. {float(given):.1e})"
    elif isinstance(given, (list, dict)):
        msg += f", got {kind_of(given)}"
    return format_loc(loc), msg
