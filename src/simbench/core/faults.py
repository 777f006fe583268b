"""How simbench tells that the physics failed, and says why in one line naming the joint or actuator: MuJoCo's
fatal warnings (a state blown up, a buffer overflowed) and any speed above MAX_SPEED (no manipulator joint turns at
1000 rad/s: the integration diverges, long before MuJoCo's own 1e10 bound).
"""

from __future__ import annotations

import mujoco
import numpy as np

_W = mujoco.mjtWarning
FATAL = {int(w) for w in (_W.mjWARN_BADQACC, _W.mjWARN_BADQPOS, _W.mjWARN_BADQVEL, _W.mjWARN_BADCTRL,
                          _W.mjWARN_CNSTRFULL, _W.mjWARN_CONTACTFULL)}
MAX_SPEED = 1e3  # rad/s or m/s, any DOF


class Fault(Exception):
    """Raised inside a stepping loop at the first step at fault: its index among the steps, and why."""

    def __init__(self, step: int, cause: str):
        self.step = step
        self.cause = cause


def _ignore(message: str) -> None:
    """MuJoCo's warning printer while it is kept quiet."""


class quiet_mujoco:  # used as a function: `with quiet_mujoco():`
    """Silence MuJoCo's printing of warnings (and its MUJOCO_LOG.TXT) inside a `with` block: simbench reads them
    from the data. A class, not a generator: an environment enters one every control step."""

    def __enter__(self) -> None:
        self._previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(_ignore)

    def __exit__(self, *exc: object) -> None:
        mujoco.set_mju_user_warning(self._previous)


def warnings_raised(data: mujoco.MjData) -> list[int]:
    """The codes of the warnings counted in data since they were last cleared."""
    return [int(i) for i in np.flatnonzero(data.warning.number)]


def clear_warnings(data: mujoco.MjData) -> None:
    """Zero every warning counter (one array write: a sweep clears them every run)."""
    data.warning.number[:] = 0


def step_fault(model: mujoco.MjModel, data: mujoco.MjData) -> str | None:
    """Why the state a step has just left cannot be trusted (a fatal warning, or an unsound state), or None."""
    fatal = [c for c in warnings_raised(data) if c in FATAL]
    if fatal:
        return warning_cause(model, fatal[0], int(data.warning[fatal[0]].lastinfo))
    return unsound(model, data.qpos, data.qvel)


def _dof(model: mujoco.MjModel, dof: int) -> str:
    return f"DOF {dof} (joint '{model.joint(int(model.dof_jntid[dof])).name}')"


def warning_cause(model: mujoco.MjModel, code: int, info: int) -> str:
    """What a fatal MuJoCo warning means, naming the joint or actuator."""
    code = _W(code)
    if code in (_W.mjWARN_BADQACC, _W.mjWARN_BADQVEL):
        quantity = "acceleration" if code == _W.mjWARN_BADQACC else "velocity"
        where = f" at {_dof(model, info)}" if 0 <= info < model.nv else ""
        what = f"{quantity} NaN, infinite or huge{where}"
    elif code == _W.mjWARN_BADQPOS:
        what = f"position NaN, infinite or huge at qpos[{info}]"
    elif code == _W.mjWARN_BADCTRL:
        where = f" at actuator '{model.actuator(info).name}'" if 0 <= info < model.nu else ""
        what = f"control NaN, infinite or huge{where}"
    else:
        buffer = "constraint" if code == _W.mjWARN_CNSTRFULL else "contact"
        what = f"the {buffer} buffer is full (the model's <size memory> is too small)"
    return f"{what} ({code.name})"


def unsound(model: mujoco.MjModel, qpos: np.ndarray, qvel: np.ndarray) -> str | None:
    """Why a state (or the last of several) cannot be trusted, or None."""
    if not (np.isfinite(qpos).all() and np.isfinite(qvel).all()):
        return "the state became NaN or infinite"
    fast = np.abs(qvel) > MAX_SPEED
    if fast.any():
        dof = int(np.flatnonzero(fast.reshape(-1, model.nv).any(axis=0))[0])
        return (f"the speed of {_dof(model, dof)} passed {MAX_SPEED:g} rad/s or m/s: the integration is "
                "diverging")
    return None


def fatal_cause(err: mujoco.FatalError) -> str:
    """MuJoCo's fatal error, on one line."""
    first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
    hint = " (the model's <size memory> is too small)" if "out of memory" in first else ""
    return f"MuJoCo stopped: {first}{hint}"
