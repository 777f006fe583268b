"""Domain randomisation and noise for the RL mode (`simbench.env.rl_mode`), both off unless asked for.

`Randomisation`: at every reset, before the settle, each quantity is drawn uniformly within its range from the
task's random state (`RLTrack.noise_random`: the RL mode's `seed`, or what shimmy's `reset(seed=...)` sets) and
the model changed from its nominal values (mj_setConst then recomputes what depends on them, such as the subtree
masses and the solver's mean inertia). The controller's side stays nominal: the residual action's servo reads the
model as loaded. What was drawn is `RLTrack.drawn` (and, with `observe`, the observation's `randomised` entry, in
the order of DRAWN).

`Noise`: zero-mean Gaussian, drawn every control step from the same random state, on the measured joints and tool
in the observation (the references are exact) and on the normalised action before it is clipped to [-1, 1].
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import mujoco
import numpy as np

from simbench.api import Array
from simbench.core.plant import Plant

DRAWN = ("mass", "damping", "friction", "contact_friction", "gain", "delay")
"""What a Randomisation may draw, in the order of the observation's `randomised` entry."""


@dataclass(frozen=True)
class Randomisation:
    """The ranges each reset draws within (uniform; low == high fixes a value; None leaves the quantity nominal).

    Attributes:
        mass: A factor on each body's mass and inertia, one a body (the world excepted).
        damping: A factor on each robot joint's viscous damping.
        friction: Each robot joint's dry friction (frictionloss) added, as a fraction of its actuator's force
            limit (a joint without one keeps its own).
        contact_friction: One factor on every geom's sliding friction.
        gain: A factor on each joint actuator's gain (a position servo's kp: its gain and its bias on q).
        delay: How many control steps (integers, both ends included) an action waits before it takes effect;
            until then the action before it holds (at the start: the one that holds the start pose).
        observe: Whether the observation shows what was drawn (`randomised`, in the order of DRAWN).
    """

    mass: tuple[float, float] | None = (0.8, 1.2)
    damping: tuple[float, float] | None = (0.5, 1.5)
    friction: tuple[float, float] | None = (0.0, 0.01)
    contact_friction: tuple[float, float] | None = (0.8, 1.2)
    gain: tuple[float, float] | None = (0.9, 1.1)
    delay: tuple[int, int] | None = (0, 1)
    observe: bool = False

    def __post_init__(self):
        for name in DRAWN:
            span = getattr(self, name)
            if span is None:
                continue
            ok = (len(span) == 2 and all(np.isfinite(v) and v >= 0 for v in span) and span[0] <= span[1])
            if name == "delay":
                ok = ok and all(float(v).is_integer() for v in span)
            if not ok:
                kind = "whole numbers of control steps" if name == "delay" else "numbers"
                raise ValueError(f"rl randomise.{name}: a range (low, high) of {kind} with 0 <= low <= high "
                                 f"expected, got {span!r}")
            object.__setattr__(self, name, tuple(int(v) if name == "delay" else float(v) for v in span))


@dataclass(frozen=True)
class Noise:
    """Standard deviations of the Gaussian noise (0: none).

    Attributes:
        q: On each measured joint position (rad or m).
        qd: On each measured joint rate (rad/s or m/s).
        tool: On each coordinate of the measured tool point (m).
        action: On each normalised action, before it is clipped to [-1, 1].
    """

    q: float = 1e-3
    qd: float = 1e-2
    tool: float = 1e-3
    action: float = 0.01

    def __post_init__(self):
        for field in fields(self):
            value = getattr(self, field.name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value >= 0):
                raise ValueError(f"rl noise.{field.name}: a standard deviation >= 0 expected, got {value!r}")


def as_settings(cls: type, value: object, name: str):
    """A Randomisation or Noise from what the RL mode was given: True (the defaults), a dict of fields, an
    instance; None or False: None."""
    if value is None or value is False:
        return None
    if value is True:
        return cls()
    if isinstance(value, cls):
        return value
    if isinstance(value, dict):
        unknown = sorted(set(value) - {f.name for f in fields(cls)})
        if unknown:
            raise ValueError(f"rl {name}: no setting {unknown[0]!r}; the settings are "
                             f"{', '.join(f.name for f in fields(cls))}")
        return cls(**value)
    raise ValueError(f"rl {name}: True, a dict of settings or a {cls.__name__} expected, got {value!r}")


class Randomiser:
    """The nominal values of a physics' model and the draws that change them."""

    def __init__(self, spec: Randomisation, model: mujoco.MjModel, plant: Plant):
        self.spec = spec
        self.act, self.dof = plant.actuators, plant.dof_adr
        self.limit = plant.force_limit()
        self.nominal = {name: getattr(model, name).copy() for name in
                        ("body_mass", "body_inertia", "dof_damping", "dof_frictionloss", "geom_friction",
                         "actuator_gainprm", "actuator_biasprm")}
        self.sizes = {"mass": model.nbody - 1, "damping": len(self.dof), "friction": len(self.dof),
                      "contact_friction": 1, "gain": len(self.act), "delay": 1}  # of each quantity drawn

    def unchanged(self) -> dict[str, Array]:
        """What a draw that leaves the model nominal gives (factors 1, no friction added, no delay), by name in the
        order of DRAWN: RLTrack.drawn before its first reset."""
        value = {"mass": 1.0, "damping": 1.0, "friction": 0.0, "contact_friction": 1.0, "gain": 1.0, "delay": 0.0}
        return {name: np.full(self.sizes[name], value[name]) for name in DRAWN if getattr(self.spec, name) is not None}

    def draw(self, random: np.random.RandomState, model: mujoco.MjModel, data: mujoco.MjData) -> dict[str, Array]:
        """The model back at its nominal values, then a new draw applied; `data` is left at qpos0 (mj_setConst).

        Returns:
            What was drawn, by name, in the order of DRAWN (those the Randomisation draws).
        """
        spec, nominal = self.spec, self.nominal
        for name, value in nominal.items():
            getattr(model, name)[:] = value
        drawn: dict[str, Array] = {}
        for name in DRAWN:
            span = getattr(spec, name)
            if span is None:
                continue
            if name == "delay":
                drawn[name] = np.array([random.randint(span[0], span[1] + 1)], dtype=float)
            else:
                drawn[name] = random.uniform(span[0], span[1], self.sizes[name])
        if "mass" in drawn:
            model.body_mass[1:] *= drawn["mass"]
            model.body_inertia[1:] *= drawn["mass"][:, None]
        if "damping" in drawn:
            model.dof_damping[self.dof] *= drawn["damping"]
        if "friction" in drawn:
            model.dof_frictionloss[self.dof] += np.where(np.isfinite(self.limit), drawn["friction"] * self.limit, 0.0)
        if "contact_friction" in drawn:
            model.geom_friction[:, 0] *= drawn["contact_friction"][0]
        if "gain" in drawn:
            model.actuator_gainprm[self.act, 0] *= drawn["gain"]
            model.actuator_biasprm[self.act, 1] *= drawn["gain"]
        mujoco.mj_setConst(model, data)
        return drawn
