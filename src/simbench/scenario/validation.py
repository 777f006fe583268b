"""Reading YAML input, and pydantic's validation errors as one line naming the field as the user wrote it
(`task.goal[1]`): shared by scenario and sweep files so that both fail the same way."""

from __future__ import annotations

import difflib
import errno
import os
import re
import stat
import typing
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError
from pydantic_core import ErrorDetails

from simbench.core.errors import MAX_INT_DIGITS, ScenarioError, os_words, printable, shown

_Model = TypeVar("_Model", bound=BaseModel)

_MAX_BYTES = 1 << 20
_MAX_VALUES = 100_000  # a scenario has hundreds; an alias bomb has billions once expanded
_MAX_DEPTH = 32
_MERGE = "tag:yaml.org,2002:merge"


class _Refused(yaml.MarkedYAMLError):
    """Valid YAML that simbench does not take (a merge key, say): said as it is, not as a syntax error."""


class _StrictLoader(yaml.SafeLoader):
    """YAML's safe loader, refusing duplicate keys (YAML keeps the last silently), merge keys (their copies can
    grow exponentially before anything counts them), non-scalar keys and values Python cannot build."""

    def construct_object(self, node, deep=False):
        if node.tag == _MERGE:  # `<<` as a value: YAML reads it as the merge key, not as text
            raise _Refused(None, None, "'<<' is YAML's merge key: write it in quotes ('<<') to mean the text",
                           node.start_mark)
        try:
            return super().construct_object(node, deep=deep)
        except (ValueError, OverflowError) as err:
            kind = str(node.tag).rsplit(":", 1)[-1]
            raise _Refused(None, None, f"cannot read this {kind}: {printable(str(err).splitlines()[0])}",
                           node.start_mark) from None

    def construct_yaml_int(self, node):
        digits = sum(c.isdigit() for c in str(node.value))
        if digits > MAX_INT_DIGITS or len(str(node.value)) > 4 * MAX_INT_DIGITS:
            raise _Refused(None, None, f"an integer of {digits} digits is too long (at most {MAX_INT_DIGITS})",
                           node.start_mark)
        value = super().construct_yaml_int(node)
        if value.bit_length() > MAX_INT_DIGITS * 3.32:  # written in hexadecimal, binary or octal
            raise _Refused(None, None, f"an integer of about {int(value.bit_length() * 0.30103) + 1} digits is "
                                       f"too long (at most {MAX_INT_DIGITS})", node.start_mark)
        return value

    def construct_mapping(self, node, deep=False):
        seen = {}
        for key_node, _ in node.value:
            if key_node.tag == _MERGE:
                raise _Refused(None, None, "YAML merge keys (<<) are not supported: write the fields out",
                               key_node.start_mark)
            if isinstance(key_node, (yaml.SequenceNode, yaml.MappingNode)):
                what = "list" if isinstance(key_node, yaml.SequenceNode) else "mapping"
                raise _Refused(None, None, f"a {what} as a key is not supported: keys are field names",
                               key_node.start_mark)
            key = self.construct_object(key_node, deep=deep)
            if isinstance(key, (str, int, float, bool)) and key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key '{printable(key)}' (first at line {seen[key] + 1})",
                    key_node.start_mark)
            seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep=deep)


_StrictLoader.add_constructor("tag:yaml.org,2002:int", _StrictLoader.construct_yaml_int)


def read_yaml(path: Path, what: str = "scenario") -> Any:
    """The YAML document in `path` (a file of `what` fields); ScenarioError if it cannot be read, is too large, not
    UTF-8, not YAML, nested too deeply, too large once its aliases are expanded, or empty."""
    path = Path(path)
    source = str(path)
    _check_file(path, source)
    data = _parse(_read_text(path, source), source)
    if data is None:
        raise ScenarioError(source, None, f"empty file: expected a mapping of {what} fields")
    _check_shape(data, source)
    return data


def _check_file(path: Path, source: str) -> None:
    """ScenarioError unless `path` is a regular file of at most _MAX_BYTES."""
    try:
        info = os.stat(path)
    except OSError as err:
        raise ScenarioError(source, None, _unreachable(path, err)) from None
    if stat.S_ISDIR(info.st_mode):
        raise ScenarioError(source, None, "a folder, not a file (expected a YAML scenario)")
    if not stat.S_ISREG(info.st_mode):
        raise ScenarioError(source, None, "not a file (expected a YAML scenario)")
    if info.st_size > _MAX_BYTES:
        raise ScenarioError(source, None, f"file too large ({info.st_size} bytes; a scenario is at most "
                                          f"{_MAX_BYTES})")


def _read_text(path: Path, source: str) -> str:
    """The file's text; ScenarioError if it cannot be read, has grown past _MAX_BYTES, or is not UTF-8."""
    try:
        with open(path, "rb") as f:
            raw = f.read(_MAX_BYTES + 1)
    except OSError as err:
        words = "permission denied: cannot read it" if err.errno in (errno.EACCES, errno.EPERM) else os_words(err)
        raise ScenarioError(source, None, words) from None
    if len(raw) > _MAX_BYTES:  # it grew since
        raise ScenarioError(source, None, f"file too large (a scenario is at most {_MAX_BYTES} bytes)")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ScenarioError(source, None, "not a text file (expected UTF-8 YAML)") from None


def _parse(text: str, source: str) -> Any:
    """The YAML document in `text`, as plain data; ScenarioError saying where and why it is refused."""
    try:
        return yaml.load(text, Loader=_StrictLoader)  # a SafeLoader: builds plain data, never objects
    except _Refused as err:
        mark = err.problem_mark
        raise ScenarioError(source, None, f"line {mark.line + 1}, column {mark.column + 1}: {err.problem}") from None
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise ScenarioError(source, None, f"not valid YAML{where}: {problem}") from None
    except RecursionError:
        raise ScenarioError(source, None, f"nested too deeply (at most {_MAX_DEPTH} levels)") from None


def _unreachable(path: Path, err: OSError) -> str:
    """Why a file cannot even be looked at (its stat failed), in words."""
    if err.errno == errno.ENOENT:
        return "no such file (a symlink to a missing file)" if os.path.islink(path) else "no such file"
    if err.errno in (errno.EACCES, errno.EPERM):
        return "permission denied: a folder on its path cannot be entered"
    return os_words(err)


def _check_shape(data: Any, source: str) -> None:
    """Refuse a document nested over _MAX_DEPTH deep or holding over _MAX_VALUES values once its aliases are
    expanded (a billion-laughs file is 2 KB)."""
    count, stack = 0, [(data, 0)]
    while stack:
        node, depth = stack.pop()
        count += 1
        if count > _MAX_VALUES:
            raise ScenarioError(source, None, f"too large once its YAML aliases are expanded (more than "
                                              f"{_MAX_VALUES} values)")
        if depth > _MAX_DEPTH:
            raise ScenarioError(source, None, f"nested too deeply (at most {_MAX_DEPTH} levels)")
        if isinstance(node, dict):
            stack.extend((v, depth + 1) for v in node.values())
        elif isinstance(node, list):
            stack.extend((v, depth + 1) for v in node)


def kind_of(value: Any) -> str:
    return {list: "a list", str: "a string", int: "a number", float: "a number", bool: "a boolean"}.get(
        type(value), f"a {type(value).__name__}")


def format_loc(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _fields_at(cls: type[BaseModel], loc: tuple) -> list[str]:
    """Field names of the model(s) at pydantic's error location `loc` from cls (for 'did you mean'); where a
    union's member is not named, the fields of all of them."""
    return list(dict.fromkeys(name for m in _models_at(cls, loc) for name in m.model_fields))


def _models_at(cls: type[BaseModel], loc: tuple) -> list[type[BaseModel]]:
    """The model(s) at pydantic's error location `loc` from cls: a union's members where `loc` names none."""
    models = [cls]
    for part in loc:
        if isinstance(part, int):
            continue
        named = _named(models, part)
        if named:
            models = named
            continue
        fields = [m.model_fields[part] for m in models if part in m.model_fields]
        if not fields:
            continue  # a tag pydantic puts in the location of a tagged union's member
        models = [m for f in fields for m in _models_in(f.annotation)]
    return models


def _named(models: list[type[BaseModel]], part: Any) -> list[type[BaseModel]]:
    """The models a union member's tag in a location names: its class name, or validators wrapping it
    (function-after[..., function-after[..., Name]])."""
    return [m for m in models if isinstance(part, str)
            and (part == m.__name__ or part.rstrip("]").endswith((f", {m.__name__}", f"[{m.__name__}")))]


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    """The pydantic models an annotation holds, itself or inside Optional, Union, Annotated, list or dict."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models_in(arg)]


def _member_name(part: Any) -> bool:
    """Whether a part of pydantic's error location names a union member pydantic tried, not a key of the document:
    a type (`float`, `list[...]`, a constrained number's `constrained-float`) or a model's class name."""
    return isinstance(part, str) and (part in ("float", "int", "str", "bool") or "[" in part or part[:1].isupper()
                                      or part.startswith("constrained-"))


def _field_loc(loc, document: Any) -> tuple:
    """A pydantic error location as the user wrote it, without the names of the union members pydantic tried."""
    out, node = [], document
    for part in loc:
        if isinstance(node, dict) and part in node or isinstance(node, list) and isinstance(part, int) \
                and 0 <= part < len(node):
            out.append(part)
            node = node[part]
        elif _member_name(part):
            continue
        else:  # a field the document lacks: missing, or the path ends here
            out.append(part)
            node = None
    return tuple(out)


def _reads_as_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def describe(err: ValidationError, cls: type[BaseModel], document: Any, prefix: tuple = ()) -> tuple[str, str]:
    """The first validation error of `document` as (field path, message in the user's terms), of a union's member
    the mapping names by its key, or that takes its shape (_fitting). An unknown field goes first: a misspelt name
    also makes the field it meant go missing."""
    errors = _fitting(err.errors(include_url=False), document, cls)
    first = _first_error(errors, document)
    where = _field_loc(first["loc"], document)
    loc = prefix + where
    if first["type"] == "missing":
        return format_loc(loc), "missing: this field is required"
    if first["type"] == "extra_forbidden":
        return format_loc(loc), _unknown_field(cls, _unknown_loc(cls, tuple(first["loc"]), document), str(loc[-1]))
    msg = _union_message(first, [e for e in errors if e is not first and _field_loc(e["loc"], document) == where])
    if msg.startswith("Value error, "):
        return format_loc(loc), msg.removeprefix("Value error, ")
    return format_loc(loc), _in_user_terms(msg, first.get("input"))


def _member(loc: tuple, document: Any) -> int | None:
    """The index in pydantic's `loc` of the first union member's name (a part _field_loc leaves out), or None."""
    node = document
    for i, part in enumerate(loc):
        if isinstance(node, dict) and part in node or isinstance(node, list) and isinstance(part, int) \
                and 0 <= part < len(node):
            node = node[part]
        elif _member_name(part):
            return i
        else:
            return None
    return None


def _misfits(error: ErrorDetails, at: int) -> bool:
    """Whether the error says its union member (named at loc[at]) does not take the value's shape at all: a wrong
    type or literal for the member itself, or a field it lacks or does not know."""
    depth = len(error["loc"]) - at
    return (depth == 1 and (error["type"].endswith("_type") or error["type"] == "literal_error")
            or depth == 2 and error["type"] in ("missing", "extra_forbidden"))


def _fitting(errors: list[ErrorDetails], document: Any, cls: type[BaseModel]) -> list[ErrorDetails]:
    """The errors of the union member a mapping names by its key (_keyed) where it names one; else without those
    of a union's members that do not take the value's shape, where another member of that union does (its errors
    then say what is wrong: a `tool: {body, offset}` with a bad offset is not told that `body` is unknown to
    `{site}`)."""
    members: dict[tuple, dict[Any, list[ErrorDetails]]] = {}
    for e in errors:
        at = _member(tuple(e["loc"]), document)
        if at is not None:
            members.setdefault(tuple(e["loc"][:at]), {}).setdefault(e["loc"][at], []).append(e)
    dropped = set()
    for where, by_member in members.items():
        keyed = _keyed(cls, where, document)
        misfit = ({m for m in by_member if not _named([keyed], m)} if keyed is not None else
                  {m for m, found in by_member.items() if any(_misfits(e, len(where)) for e in found)})
        if len(misfit) < len(by_member):
            dropped |= {id(e) for m in misfit for e in by_member[m]}
    return [e for e in errors if id(e) not in dropped]


def _keyed(cls: type[BaseModel], where: tuple, document: Any) -> type[BaseModel] | None:
    """The one model of the union at `where` whose discriminating key the document's mapping there holds: a field
    that model requires and no other model of the union has (`body` of `tool: {body: ...}`, `site` of
    `{site: ...}`); None where none, or more than one, is named so."""
    node = document
    for part in where:
        node = node[part]
    if not isinstance(node, dict):
        return None
    models = _models_at(cls, where)

    def names(model: type[BaseModel]) -> bool:
        return any(f.is_required() and key in node and all(key not in other.model_fields for other in models
                                                               if other is not model)
                   for key, f in model.model_fields.items())

    named = [m for m in models if names(m)]
    return named[0] if len(named) == 1 else None


def _unknown_loc(cls: type[BaseModel], loc: tuple, document: Any) -> tuple:
    """The location of the model whose fields an unknown field at `loc` (pydantic's) is told of: its union
    member's, unless no member is named by its key (_keyed) and none has that field, where every member's."""
    parent = loc[:-1]
    at = _member(parent, document)
    if at is None or _keyed(cls, parent[:at], document) is not None:
        return parent
    union = parent[:at] + parent[at + 1:]
    return parent if loc[-1] in _fields_at(cls, union) else union


def _first_error(errors: list[ErrorDetails], document: Any) -> ErrorDetails:
    """An unknown field, else the first error that no other lies within, else the first (of the errors _fitting
    kept)."""
    locs = [_field_loc(e["loc"], document) for e in errors]

    def inside(i: int) -> bool:  # another error lies within this one's mapping or list
        return isinstance(errors[i].get("input"), (dict, list)) and any(
            len(other) > len(locs[i]) and other[:len(locs[i])] == locs[i] for other in locs)

    return next((e for e in errors if e["type"] == "extra_forbidden"),
                next((e for i, e in enumerate(errors) if not inside(i)), errors[0]))


def _unknown_field(cls: type[BaseModel], parent: tuple, name: str) -> str:
    """The message for an unknown field `name` in the model at `parent`: the fields it has, and the nearest."""
    fields = _fields_at(cls, parent)
    if not fields:  # a mapping whose model the location does not lead to: no list to offer, rather than an empty one
        return "unknown field (not one this mapping takes: see the docs' Scenarios page, docs/guide/scenarios.md)"
    return f"unknown field (expected one of: {', '.join(fields)}){did_you_mean(name, fields)}"


def did_you_mean(name: str, options) -> str:
    """The "; did you mean 'x'?" naming the option nearest `name`, or "" where none is near."""
    hint = difflib.get_close_matches(name, options, n=1)
    return f"; did you mean '{hint[0]}'?" if hint else ""


def _union_message(first: ErrorDetails, same_field: list[ErrorDetails]) -> str:
    """pydantic's message for `first`, joined with what each other member of a union expects."""
    msg = first["msg"]
    alike = [e["msg"] for e in same_field if e["msg"].startswith("Input should be")]
    if alike and msg.startswith("Input should be"):
        msg = " or ".join([msg] + [m.removeprefix("Input should be ") for m in alike])
    return msg


_COUNT = re.compile(r"^\w+ should have at (least|most) (\d+) items? after validation, not (\d+)$")


def _in_user_terms(msg: str, given: Any) -> str:
    """pydantic's message as what is expected and what was given (with a hint where YAML read a number as text)."""
    msg = msg.replace("Input should be", "expected").replace("String should", "expected a string to")
    msg = re.sub(r"a valid dictionary or instance of \w+", "a mapping of its fields", msg)
    if msg.startswith("expected "):  # each alternative once (two models' mappings read alike)
        msg = "expected " + " or ".join(dict.fromkeys(msg.removeprefix("expected ").split(" or ")))
    counted = _COUNT.match(msg)  # a list or mapping of too few or too many items
    if counted:
        least, bound, found = counted.groups()
        return f"expected at {least} {bound} item{'s' * (bound != '1')}, got {found}"
    if isinstance(given, (str, int, float, bool)) or given is None:
        msg += f", got {shown(given)}"
        if isinstance(given, str) and _reads_as_number(given) and len(given) < 40:
            msg += f" (YAML reads {given} as text: write it with a decimal point, e.g. {float(given):.1e})"
    elif isinstance(given, (list, dict)):
        msg += f", got {kind_of(given)}"
    return msg


def read_spec(path: Path, cls: type[_Model], what: str) -> _Model:
    """A YAML file of `what` fields (a sweep's, a suite's) validated by `cls`; ScenarioError naming the file and
    the field at fault."""
    source = str(path)
    raw = read_yaml(path, what)
    if not isinstance(raw, dict):
        raise ScenarioError(source, None, f"expected a mapping of {what} fields, got {kind_of(raw)}")
    try:
        return cls.model_validate(raw)
    except ValidationError as err:
        raise ScenarioError(source, *describe(err, cls, raw)) from None
