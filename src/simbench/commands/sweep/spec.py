"""Sweep files (docs/guide/sweeps.md): a base scenario and the parameters to vary, expanded into one scenario
document per run. A parameter is a field path (`task.goal[1]`) set in the base's YAML document before it is
validated, so it takes the base file's units and a value the schema refuses makes that run a `bad_input` row.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import AfterValidator, Field, model_validator

from simbench.commands.sweep import size
from simbench.commands.sweep.size import MAX_RUNS
from simbench.core.errors import ScenarioError
from simbench.core.resources import scenarios_dir
from simbench.scenario import parse_scenario, robot_mapping
from simbench.scenario.schema import MAX_NAME, Name, SimbenchModel, file_name
from simbench.scenario.validation import kind_of, read_spec, read_yaml

_PATH = re.compile(r"[A-Za-z_]\w*(?:\.[A-Za-z_]\w*|\[\d+\])*")
_PART = re.compile(r"\.?([A-Za-z_]\w*)|\[(\d+)\]")
_KINDS = ("uniform", "loguniform", "normal", "integers", "choice")

MAX_BOUND = 1e15  # no scenario field is larger: a wider distribution is a typo, and its draws would overflow
Bound = Annotated[float, Field(ge=-MAX_BOUND, le=MAX_BOUND)]


def _alike(pair: list) -> list:
    """Two bounds, both numbers or both lists (a number beside a list has no shape to draw)."""
    if isinstance(pair[0], list) != isinstance(pair[1], list):
        raise ValueError("expected both bounds numbers, or both lists of the same length, got a number and a list")
    return pair


Pair = Annotated[list[Bound | list[Bound]], Field(min_length=2, max_length=2), AfterValidator(_alike)]
Integer = Annotated[int, Field(ge=-2**53, le=2**53)]


class Distribution(SimbenchModel):
    """How a random parameter is drawn: exactly one of the fields. Bounds may be vectors, drawn item by item."""

    uniform: Pair | None = None
    loguniform: Pair | None = None
    normal: Pair | None = None
    integers: Annotated[list[Integer], Field(min_length=2, max_length=2)] | None = None
    choice: Annotated[list[Any], Field(min_length=1)] | None = None

    @property
    def kind(self) -> str:
        """The one field given."""
        return next(k for k in _KINDS if getattr(self, k) is not None)

    @model_validator(mode="after")
    def _one_kind(self):
        given = sum(getattr(self, k) is not None for k in _KINDS)
        if given != 1:
            raise ValueError(f"expected exactly one of {', '.join(_KINDS)}, got {given}")
        kind = self.kind
        if kind in ("uniform", "loguniform", "normal"):
            a, b = (np.atleast_1d(np.asarray(v, float)) for v in getattr(self, kind))
            if a.shape != b.shape:
                raise ValueError(f"{kind}: its two bounds must be the same length, got {a.size} and {b.size}")
            if kind == "normal" and (b < 0).any():
                raise ValueError("normal: [mean, standard deviation] with the deviation >= 0")
            if kind != "normal" and (a > b).any():
                raise ValueError(f"{kind}: [low, high] with low <= high")
            if kind == "loguniform" and (a <= 0).any():
                raise ValueError("loguniform: bounds must be > 0")
        if kind == "integers" and self.integers[0] > self.integers[1]:
            raise ValueError("integers: [low, high] with low <= high (both included)")
        return self

    def draw(self, rng: np.random.Generator) -> Any:
        """One value: a float, an int, a list of floats for vector bounds, or one of the choices."""
        kind = self.kind
        if kind == "choice":
            return copy.deepcopy(self.choice[int(rng.integers(len(self.choice)))])
        if kind == "integers":
            return int(rng.integers(self.integers[0], self.integers[1] + 1))
        a_raw, b_raw = getattr(self, kind)
        a, b = np.asarray(a_raw, float), np.asarray(b_raw, float)
        if kind == "loguniform":
            value = np.exp(rng.uniform(np.log(a), np.log(b)))
        else:  # uniform, normal: the Generator's method of that name
            value = getattr(rng, kind)(a, b)
        return value.tolist() if isinstance(a_raw, list) else float(value)


class RandomSpec(SimbenchModel):
    """Seeded random samples of some parameters."""

    samples: Annotated[int, Field(ge=1, le=MAX_RUNS)]
    seed: Annotated[int, Field(ge=0, le=2**63 - 1)] = 0
    params: Annotated[dict[str, Distribution], Field(min_length=1)]


class SweepSpec(SimbenchModel):
    """A sweep file as written."""

    name: Name | None = None
    description: str = ""
    base: Annotated[str, Field(min_length=1)]
    grid: dict[str, Annotated[list[Any], Field(min_length=1)]] = {}
    random: RandomSpec | None = None
    outputs: Literal["none", "report", "full"] = "report"
    video: bool = False
    plots: list[str] = ["tool_rms", "tool_max"]

    @model_validator(mode="after")
    def _consistent(self):
        if not self.grid and self.random is None:
            raise ValueError("nothing to vary: give a grid, random samples, or both")
        if self.video and self.outputs != "full":
            raise ValueError("video: true needs outputs: full (a video is kept only with every other output)")
        return self


@dataclass(frozen=True)
class Variant:
    """One run of a sweep: its parameters as written and the scenario document they make."""

    index: int
    id: str
    params: dict[str, Any]
    document: dict


@dataclass(frozen=True)
class Sweep:
    """A validated sweep file and every run it makes."""

    name: str
    source: str
    spec: SweepSpec
    base: Path
    variants: tuple[Variant, ...]
    _SPEC_KEY: ClassVar[str] = "spec"  # the spec's key in the fingerprint's document

    @property
    def params(self) -> list[str]:
        """The swept field paths: grid first, then random, as written."""
        return list(self.spec.grid) + (list(self.spec.random.params) if self.spec.random else [])

    def fingerprint(self) -> str:
        """A hash of everything that decides the results: a sweep resumes only into a folder with the same one."""
        from simbench.core.version import __version__

        blob = json.dumps({"simbench": __version__, self._SPEC_KEY: self.spec.model_dump(mode="json"),
                           "runs": [v.document for v in self.variants]}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()


def parse_path(text: str) -> tuple[str | int, ...]:
    """'task.goal[1]' -> ('task', 'goal', 1); ValueError if it is not a field path."""
    if not _PATH.fullmatch(text):
        raise ValueError(f"'{text}' is not a field path (expected names joined by '.', list items as [i], "
                         "e.g. task.goal[1])")
    return tuple(name if name else int(index) for name, index in _PART.findall(text))


def assign(document: dict, path: tuple[str | int, ...], value: Any) -> None:
    """Set the field at `path`, creating missing mappings; a list item must already exist in the base."""
    node: Any = document
    for depth, part in enumerate(path):
        where = ".".join(str(p) for p in path[:depth]) or "the document"
        last = depth == len(path) - 1
        if isinstance(part, int):
            if not isinstance(node, list):
                raise ValueError(f"the base's {where} is {kind_of(node)}, not a list to index with [{part}]")
            if part >= len(node):
                raise ValueError(f"the base's {where} has {len(node)} items, no item [{part}]")
        elif not isinstance(node, dict):
            raise ValueError(f"the base's {where} is {kind_of(node)}, not a mapping with a field '{part}'")
        if last:
            node[part] = copy.deepcopy(value)
        else:
            if isinstance(part, str) and part not in node:
                if isinstance(path[depth + 1], int):  # (a mapping made here has no items)
                    field = part if depth == 0 else f"{where}.{part}"
                    raise ValueError(f"the base has no field {field} (a list indexed with [{path[depth + 1]}] must "
                                     "be in the base)")
                node[part] = {}
            node = node[part]


def load_sweep(path: str | Path) -> Sweep:
    """Read and validate a sweep file and expand it into its runs.

    Args:
        path: The sweep file (YAML): its base scenario, grid and random samples.

    Returns:
        The sweep, its variants expanded (each a scenario document and its parameters).

    Raises:
        ScenarioError: naming the file and the field at fault, or a sweep too large for the machine's memory.
    """
    path = Path(path)
    source = str(path)
    spec = read_spec(path, SweepSpec, "sweep")
    base = _find_base(spec.base, path.parent, source)
    document = read_yaml(base)
    parse_scenario(document, str(base), default_name=base.stem)  # the base alone must be a valid scenario
    paths = _paths(spec, source)
    runs = size.check(spec, document, source).runs  # before anything is expanded: it may not fit in memory
    variants = _expand(spec, document, paths, base, runs, source)
    _check_fields(variants[0], paths, source)
    return Sweep(spec.name or file_name(path.stem, source), source, spec, base, tuple(variants))


def _find_base(text: str, folder: Path, source: str) -> Path:
    """The base scenario: a path relative to the sweep file, or a shipped scenario named robot/name."""
    for candidate in (folder / text, scenarios_dir() / text, scenarios_dir() / f"{text}.yaml"):
        if candidate.is_file():
            return candidate
    try:
        os.lstat(folder / text)
        return folder / text  # there, but no readable file (a folder, a symlink loop): read_yaml says which
    except FileNotFoundError:
        pass
    except OSError:
        return folder / text  # a file in the way, a folder that cannot be entered: read_yaml words it
    raise ScenarioError(source, "base", f"no scenario file '{text}' (expected a path relative to the sweep file "
                                        "or a shipped scenario such as spherical_arm/case1)")


def _paths(spec: SweepSpec, source: str) -> dict[str, tuple[str, tuple[str | int, ...]]]:
    """Every swept field path: the sweep file's section that sweeps it (grid or random.params) and the path
    parsed; a field may be swept once, by one path (not by two spellings of it, nor by a path and one within it:
    the later assignment would override the earlier, and a column of the table would not be what ran)."""
    found: dict[str, tuple[str, tuple[str | int, ...]]] = {}
    sections = [("grid", spec.grid)] + ([("random.params", spec.random.params)] if spec.random else [])
    for section, fields in sections:
        for text in fields:
            try:
                found_path = parse_path(text)
            except ValueError as err:
                raise ScenarioError(source, f"{section}.{text}", str(err)) from None
            for other, (other_section, other_path) in found.items():
                shorter = min(len(found_path), len(other_path))
                if found_path[:shorter] == other_path[:shorter]:
                    how = "swept twice" if len(found_path) == len(other_path) else "overlaps"
                    raise ScenarioError(source, f"{section}.{text}", f"{how}: {other_section} sweeps {other}, the "
                                                                     "same field or one holding it or within it")
            found[text] = (section, found_path)
    return found


def _expand(spec: SweepSpec, document: dict, paths: dict, base: Path, count: int,
            source: str) -> list[Variant]:
    """Every grid point crossed with every random sample (`count` runs), numbered in that order. A robot mapping's
    relative paths (swept ones too) are made absolute against the base scenario's folder, as `simbench run` of the
    base reads them, since a run's document is read from the sweep."""
    base_name, folder = base.stem, base.parent
    grid_points = list(itertools.product(*spec.grid.values()))
    samples: list[dict[str, Any]] = [{}]
    if spec.random:
        rng = np.random.default_rng(spec.random.seed)
        samples = [{name: dist.draw(rng) for name, dist in spec.random.params.items()}
                   for _ in range(spec.random.samples)]
    width = max(4, len(str(count - 1)))
    variants = []
    for point, sample in itertools.product(grid_points, samples):
        params = {**dict(zip(spec.grid, point)), **sample}
        doc = copy.deepcopy(document)
        for name, value in params.items():
            section, path = paths[name]
            try:
                assign(doc, path, value)
            except ValueError as err:
                raise ScenarioError(source, f"{section}.{name}", str(err)) from None
        if robot_mapping.is_mapping(doc.get("robot")):  # read from the sweep, its files named as from the base
            doc["robot"] = robot_mapping.anchored(doc["robot"], folder)
        index = len(variants)
        run_id = f"r{index:0{width}d}"
        stem = f"{doc.get('name') or base_name}"[:MAX_NAME - len(run_id) - 1]  # cut so that the run's name fits
        doc["name"] = f"{stem}-{run_id}"
        variants.append(Variant(index, run_id, params, doc))
    return variants


def _check_fields(first: Variant, paths: dict, source: str) -> None:
    """A swept field the scenario does not have is the sweep file's error, not every run's."""
    try:
        parse_scenario(first.document, source)
    except ScenarioError as err:
        field = err.field or ""
        for name, (section, _) in paths.items():
            if err.message.startswith("unknown field") and (name == field or name.startswith((field + ".",
                                                                                              field + "["))):
                message = err.message if name == field else f"'{field}' is an {err.message}"
                raise ScenarioError(source, f"{section}.{name}", message) from None
