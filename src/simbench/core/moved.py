"""The module paths simbench had before its stage folders, kept for one release (0.2 drops them): importing one
gives the module at its new path, the same module object, with a DeprecationWarning that names the new path. A
package's submodules follow it (simbench.sweep.spec is simbench.commands.sweep.spec).

The old paths are those any outside code could have imported: every module that moved (docs/architecture.md
shows where each stage's modules are).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings
from types import ModuleType

MOVED = {
    "analysis.path_distance": "maths.path_distance",
    "atomic": "core.atomic",
    "bench": "commands.bench",
    "budget": "core.budget",
    "buffers": "core.buffers",
    "compare": "commands.compare",
    "computed_torque": "physics.computed_torque",
    "controllers": "physics.controllers",
    "csv_cells": "outputs.csv_cells",
    "destination": "core.destination",
    "drawn_planes": "outputs.drawn_planes",
    "errors": "core.errors",
    "events": "api.events",
    "export": "outputs.export",
    "extras": "core.extras",
    "faults": "core.faults",
    "figures": "outputs.figures",
    "fitting": "physics.fitting",
    "forked": "core.forked",
    "frozen": "core.frozen",
    "interrupts": "core.interrupts",
    "observation": "physics.observation",
    "page": "outputs.page",
    "paths": "maths.paths",
    "pipeline": "commands.pipeline",
    "plant": "core.plant",
    "plot_formats": "outputs.plot_formats",
    "plots": "outputs.plots",
    "policy": "physics.policy",
    "random_tasks": "planners.random_tasks",
    "recording": "api.recording",
    "registry": "api.registry",
    "render": "outputs.render",
    "report": "outputs.report",
    "reproduce": "commands.reproduce",
    "resources": "core.resources",
    "robots.inspect_arm": "commands.inspect_arm",
    "robots.robot_mapping": "scenario.robot_mapping",
    "rotations": "maths.rotations",
    "schema": "scenario.schema",
    "scoring": "analysis.scoring",
    "servo_design": "robots.servo_design",
    "sim": "physics.sim",
    "singularity_handling": "analysis.singularity_handling",
    "stepping": "physics.stepping",
    "sweep": "commands.sweep",
    "switches": "physics.switches",
    "timing": "maths.timing",
    "tracking": "analysis.tracking",
    "trajectory": "api.trajectory",
    "validation": "scenario.validation",
    "vectors": "maths.vectors",
    "verdict": "analysis.verdict",
    "version": "core.version",
    "windowed": "core.windowed",
}
"""Old path -> new path, both under simbench."""


def new_path(name: str) -> str | None:
    """The module's path now (a dotted name under simbench), or None where `name` did not move."""
    parts = name.split(".")
    if parts[0] != "simbench":
        return None
    for end in range(len(parts), 1, -1):
        moved = MOVED.get(".".join(parts[1:end]))
        if moved is not None:
            return ".".join(["simbench", moved, *parts[end:]])
    return None


class _OldPaths(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds an old path and loads it as the module at its new path."""

    def find_spec(self, fullname: str, path=None, target=None):  # noqa: ANN001 (importlib's signature)
        if new_path(fullname) is None:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec) -> ModuleType:  # noqa: ANN001
        new = new_path(spec.name)
        warnings.warn(f"{spec.name} is now {new}; the old path goes in simbench 0.2", DeprecationWarning,
                      stacklevel=2)
        return importlib.import_module(new)

    def exec_module(self, module: ModuleType) -> None:
        """Nothing to run: the module at the new path is already loaded."""


def install() -> None:
    """Let the old paths import (once a process)."""
    if not any(isinstance(finder, _OldPaths) for finder in sys.meta_path):
        sys.meta_path.insert(0, _OldPaths())
