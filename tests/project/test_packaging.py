"""What pyproject.toml declares against what simbench refuses and what constraints.txt pins: every extra a refusal
names exists and installs the module it is named for; every declared dependency is a range that the pinned test
environment satisfies, and whose lower bound is the version constraints-lowest.txt (the tested minimum) pins."""

from __future__ import annotations

import tomllib
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from simbench.core import extras

ROOT = Path(__file__).resolve().parents[2]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
OPTIONAL = PROJECT["optional-dependencies"]
# The distribution that provides each module simbench imports optionally, where the names differ.
DISTRIBUTION = {"sklearn": "scikit-learn"}


def _pins(file: str = "constraints.txt") -> dict[str, str]:
    lines = [line.strip() for line in (ROOT / file).read_text().splitlines()]
    pins = [line.split("==") for line in lines if line and not line.startswith("#")]
    assert all(len(pin) == 2 for pin in pins), f"{file}: one name==version a line"
    return {canonicalize_name(name): version for name, version in pins}


def _requirements(group: list[str]) -> list[Requirement]:
    return [Requirement(text) for text in group]


def test_each_extra_a_refusal_names_installs_its_module():
    for module, (extra, _) in extras.EXTRAS.items():
        names = {canonicalize_name(r.name) for r in _requirements(OPTIONAL[extra])}
        assert canonicalize_name(DISTRIBUTION.get(module, module)) in names, (module, extra)


def test_all_holds_every_runtime_extra_and_test_every_one_the_tests_use():
    runtime = {extra for extra, _ in extras.EXTRAS.values()}
    (everything,) = _requirements(OPTIONAL["all"])
    assert everything.name == "simbench" and set(everything.extras) == runtime
    (tested,) = [r for r in _requirements(OPTIONAL["test"]) if r.name == "simbench"]
    assert set(tested.extras) == runtime - {"train"} | {"docs"}


def test_dependencies_are_ranges_that_the_pinned_environment_meets():
    pins = _pins()
    assert not {"simbench", "simbench-planar3r"} & set(pins)
    declared = _requirements(PROJECT["dependencies"]) + [
        r for name, group in OPTIONAL.items() if name != "train" for r in _requirements(group) if r.name != "simbench"]
    for requirement in declared:
        assert not any(spec.operator == "==" for spec in requirement.specifier), f"{requirement}: a pin, not a range"
        pinned = pins.get(canonicalize_name(requirement.name))
        assert pinned is not None, f"{requirement.name} is not pinned in constraints.txt"
        assert requirement.specifier.contains(pinned), f"{requirement.name}=={pinned} outside {requirement}"


def test_every_lower_bound_is_the_version_the_lowest_environment_pins():
    """constraints-lowest.txt is the environment the tests passed in at the minimum: a lower bound raised or lowered
    in pyproject.toml without it is a bound nobody tested."""
    pins = _pins("constraints-lowest.txt")
    assert not {"simbench", "simbench-planar3r"} & set(pins)
    declared = _requirements(PROJECT["dependencies"]) + [
        r for group in OPTIONAL.values() for r in _requirements(group) if r.name != "simbench"]
    for requirement in declared:
        (lower,) = [spec.version for spec in requirement.specifier if spec.operator == ">="]
        pinned = pins.get(canonicalize_name(requirement.name))
        assert pinned == lower, f"{requirement}: constraints-lowest.txt pins {requirement.name}=={pinned}"
