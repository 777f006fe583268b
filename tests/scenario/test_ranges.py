"""Every numeric field of every shipped scenario, given absurd values (huge, tiny, negative, not finite, integers
beyond a float): refused with one line naming that field and exit 2, or accepted with every value finite and
within its range, and then planned to a result or refused as a run (never a bug).

The fields are found by walking each planner's schema, not listed, so a field added tomorrow is covered too:
the ones the shipped file writes and the ones it leaves at their defaults.
"""

import copy
import math
import types
import typing

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydantic import BaseModel

from simbench.cli import main
from simbench.commands import pipeline
from simbench.core.errors import RunError, ScenarioError
from simbench.scenario.document import _scenario_class, load_scenario, parse_scenario
from simbench.scenario.schema import MAX_ANGLE, MAX_LENGTH
from tests.conftest import SHIPPED

HUGE = [1e308, -1e308, 2.0**70, 2**70, 10**5000, -(10**5000), math.inf, -math.inf, math.nan, 1e30]
SMALL = [0.0, -0.0, 1e-308, -1e-308, 1e-12, -1.0, 0, -1]


def _members(annotation):
    """The types a field accepts: the members of a union, else the type itself."""
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return typing.get_args(annotation)
    return (annotation,)


def _numeric_paths(cls: type[BaseModel], doc: dict, prefix: tuple):
    """(path, document holding the field) for every number in `cls`'s schema that `doc` sets or could set: scalar
    fields, items of number lists (a list the document leaves out is filled with its default), and the fields
    of nested mappings, those the document leaves out included when they can be built from defaults."""
    for name, field in cls.model_fields.items():
        here = doc.get(name, None)
        for member in _members(field.annotation):
            origin, args = typing.get_origin(member), typing.get_args(member)
            if member in (float, int):
                yield prefix + (name,), None
            elif origin is list and args and args[0] in (float, int):
                items = here if isinstance(here, list) else field.default if isinstance(field.default, list) else None
                for i in range(len(items or [])):
                    yield prefix + (name, i), list(items)
            elif origin is list and args and isinstance(args[0], type) and issubclass(args[0], BaseModel):
                for i, item in enumerate(here if isinstance(here, list) else []):
                    yield from _numeric_paths(args[0], item, prefix + (name, i))
            elif isinstance(member, type) and issubclass(member, BaseModel):
                if isinstance(here, dict):
                    yield from _numeric_paths(member, here, prefix + (name,))
                elif here is None and all(not f.is_required() for f in member.model_fields.values()):
                    yield from _numeric_paths(member, {}, prefix + (name,))


def _set(doc: dict, path: tuple, value, filled: list | None) -> dict:
    """A copy of `doc` with the number at `path` replaced (creating the mappings and the default list on the way)."""
    doc = copy.deepcopy(doc)
    node = doc
    for part in path[:-1]:
        if isinstance(part, str) and part not in node:
            node[part] = list(filled) if filled is not None and part == path[-2] else {}
        node = node[part]
    node[path[-1]] = value
    return doc


def _text(path: tuple) -> str:
    return "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in path).lstrip(".")


def _id(value) -> str:
    """A test id that a 5000-digit integer does not break."""
    return f"int{value.bit_length()}bits" if isinstance(value, int) and abs(value) > 10**18 else repr(value)


CASES = []
for file in SHIPPED:
    raw = yaml.safe_load(file.read_text())
    for path, filled in _numeric_paths(_scenario_class(raw["planner"]), raw, ()):
        CASES.append((file, raw, path, filled))


def _finite_leaves(value):
    if isinstance(value, BaseModel):
        for v in value.__dict__.values():
            yield from _finite_leaves(v)
    elif isinstance(value, (list, tuple)):
        for v in value:
            yield from _finite_leaves(v)
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        yield value


def _refused_by_name(file, raw, path, filled, value, exactly=False):
    """The scenario with `value` at `path`, or the ScenarioError refusing it, checked to name that field; unless
    `exactly`, a check of several fields (a path segment out of reach at the task's orientation) may name another
    field of the same section."""
    try:
        scenario = parse_scenario(_set(raw, path, value, filled), str(file))
    except ScenarioError as err:
        field = err.field or ""
        assert field and (_text(path).startswith(field) or not exactly and field.split(".")[0] == path[0]), \
            (field, _text(path), err.message)
        assert "\n" not in str(err)
        return err
    leaves = list(_finite_leaves(scenario))
    assert all(math.isfinite(v) for v in leaves), _text(path)
    assert all(abs(v) <= max(MAX_ANGLE, 86_400.0, 1e9) for v in leaves), _text(path)
    return scenario


def test_every_shipped_scenario_has_its_numbers_found():
    """The walk finds the numbers of every planner's task, and the defaults of every section."""
    found = {(f.parent.name, _text(p)) for f, _, p, _ in CASES}
    for expected in [("spherical_arm", "task.start[3]"), ("spherical_arm", "task.nd"), ("spherical_arm", "sim.settle"),
                     ("puma600", "task.orientation.value[1]"), ("puma600", "task.path[0].line.end[2]"),
                     ("agile_eye", "task.avoidance.window"), ("agile_eye", "task.obstacles[0].radius"),
                     ("rsmg", "task.motion.axis[2]"), ("rsmg", "task.swing_time"), ("rsmg", "render.fps"),
                     ("puma600", "analysis.path_tolerance"), ("spherical_arm", "timing.duration")]:
        assert expected in found
    assert len(CASES) > 300


@pytest.mark.parametrize("value", HUGE, ids=_id)
def test_huge_and_non_finite_values_are_refused_by_name(value):
    """Every number of every shipped scenario: a value beyond any range is refused, naming that field."""
    for file, raw, path, filled in CASES:
        if path[-1] == "seed":
            continue
        result = _refused_by_name(file, raw, path, filled, value, exactly=True)
        assert isinstance(result, ScenarioError), (file.name, _text(path), value)


@pytest.mark.parametrize("value", SMALL, ids=_id)
def test_tiny_zero_and_negative_values_are_refused_by_name_or_stay_in_range(value):
    for file, raw, path, filled in CASES:
        _refused_by_name(file, raw, path, filled, value)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=st.sampled_from([c for c in CASES if "agile_eye" not in str(c[0])]),
       value=st.one_of(st.sampled_from(HUGE + SMALL), st.floats(allow_nan=True, allow_infinity=True),
                       st.integers(min_value=-(2**80), max_value=2**80)))
def test_an_accepted_value_plans_to_a_result_or_a_refusal(case, value):
    """What the schema accepts, the planner plans, or refuses as a run (exit 1): never an internal error."""
    file, raw, path, filled = case
    scenario = _refused_by_name(file, raw, path, filled, value)
    if isinstance(scenario, ScenarioError):
        return
    try:
        traj, _ = pipeline.check_plan(scenario)
    except (RunError, ScenarioError):
        return
    assert np.isfinite(traj.q_ref).all()


@pytest.mark.parametrize("value", [1e308, -(10**5000), math.nan, -math.inf, 2**70], ids=_id)
def test_the_cli_refuses_in_one_line_with_exit_2(value, tmp_path, capsys):
    """Through the command line, for one field of each section of each robot: one line, exit 2, no output."""
    seen = set()
    for file, raw, path, filled in CASES:
        key = (file.parent.name, path[0])
        if key in seen:
            continue
        seen.add(key)
        doc = _set(raw, path, "VALUE", filled)
        scenario = tmp_path / "s.yaml"
        scenario.write_text(yaml.safe_dump(doc).replace("VALUE", _yaml_number(value)))
        code = main(["run", str(scenario), "--out", str(tmp_path / "out"), "--quiet", "--no-video"])
        err = capsys.readouterr().err.splitlines()
        named = err[0].split(": ")[2] if len(err) == 1 else ""
        # the field, or where the YAML reader stopped (an integer too long to read at all)
        assert code == 2 and len(err) == 1 and (_text(path).startswith(named) or named.startswith("line ")), \
            (err, _text(path))
        assert not (tmp_path / "out").exists()


def _yaml_number(value) -> str:
    """How YAML writes the number (an integer too long for Python's str() included)."""
    if isinstance(value, int) and value.bit_length() > 1000:
        return ("-" if value < 0 else "") + "1" + "0" * 5000
    return {math.inf: ".inf", -math.inf: "-.inf"}.get(value, ".nan" if value != value else repr(value))


def test_a_loaded_scenario_cannot_be_changed_after_it_was_checked():
    sc = load_scenario(SHIPPED[0])
    for value in _lists(sc):
        with pytest.raises((TypeError, AttributeError)):
            value[0] = 1e9


def _lists(model):
    for v in model.__dict__.values():
        if isinstance(v, BaseModel):
            yield from _lists(v)
        assert not isinstance(v, list)
        if isinstance(v, tuple):
            yield v


def test_positions_and_lengths_have_the_workspace_scale():
    """A point 11 m away is refused whatever the file's unit."""
    file = next(f for f in SHIPPED if f.parent.name == "puma600" and f.name == "line.yaml")
    raw = yaml.safe_load(file.read_text())
    path = next(p for f, _, p, _ in CASES if f == file and p[-1] == 0 and "start" in p)
    factor = 1e3 if raw.get("units", {}).get("length") == "mm" else 1.0
    with pytest.raises(ScenarioError, match="coordinates"):
        parse_scenario(_set(raw, path, (MAX_LENGTH + 1) * factor, None), "x")


@pytest.mark.parametrize("call", ["run", "evaluate"])
def test_the_python_api_takes_a_scenario_or_its_path_and_says_what_else_to_pass(call, tmp_path):
    import simbench

    fn = getattr(simbench, call)
    for wrong in (None, 3, {"robot": "puma600"}):
        with pytest.raises(TypeError, match=f"simbench.{call} expects a Scenario .* or the path of a scenario file, "
                                            f"got {type(wrong).__name__}"):
            fn(wrong)
    with pytest.raises(ScenarioError, match="no such file"):
        fn(str(tmp_path / "x.yaml"))
    file = next(f for f in SHIPPED if f.name == "case1.yaml")
    kwargs = {"out": tmp_path / "out", "video": False} if call == "run" else {}
    by_path = fn(file, **kwargs)
    evaluation = by_path.evaluation if call == "run" else by_path
    assert np.array_equal(evaluation.recording.q, simbench.evaluate(load_scenario(file)).recording.q)


SWEEP_ABSURD = [("seed", -1), ("seed", 2**70), ("seed", 1.5),
                ("uniform", [-1e308, 1e308]), ("uniform", [0.0, math.inf]), ("loguniform", [1e-300, 1e300]),
                ("normal", [0.0, 1e300]), ("integers", [0, 2**70]), ("integers", [-(2**70), 0]),
                ("uniform", [[0.0, 0.0], [1.0, 1e20]])]


@pytest.mark.parametrize(("kind", "value"), SWEEP_ABSURD, ids=[f"{k}={_id(v)}" for k, v in SWEEP_ABSURD])
def test_a_sweep_with_absurd_distribution_parameters_is_refused_by_name(kind, value, tmp_path, capsys):
    """Exit 2 naming the sweep's field, before any run is drawn; never an internal error."""
    random = {"samples": 3, "params": {"timing.duration": {"uniform": [1.0, 2.0]}}}
    if kind == "seed":
        random["seed"] = value
        field = "random.seed"
    else:
        random["params"] = {"timing.duration": {kind: value}}
        field = f"random.params.timing.duration.{kind}"
    sweep = tmp_path / "s.yaml"
    sweep.write_text(yaml.safe_dump({"base": "spherical_arm/case1", "random": random}))
    code = main(["sweep", str(sweep), "--dry-run"])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and f": {field}" in err[0], err
