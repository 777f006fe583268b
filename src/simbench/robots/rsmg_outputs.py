"""What the RSMG adds to a run's outputs: report entries, re-grips as switch events, its electromagnets coloured
by state in the video, and every arm's gamma plotted (paper 001's Fig. 11; matplotlib imported only then)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from simbench import api
from simbench.maths.rotations import quat_to_matrix, rotation_angle
from simbench.robots.rsmg_geometry import ARMS, CHUNK, GAMMA_BAND, POINTS, RADIUS, gripping

if TYPE_CHECKING:
    from matplotlib.figure import Figure

_GRIPPING_RGBA = [0.2, 0.85, 0.3, 1.0]  # an EM that grips: green
_FREE_RGBA = [0.55, 0.55, 0.58, 1.0]  # an EM that is free: grey


class Summariser(api.Summariser):
    """`summary` a window of samples at a time, in order: each arm's grip anchor and state, and the last two
    samples (for a grip at a window's edge), carried from window to window."""

    def __init__(self, traj):
        self.lo = 0
        self.anchor = np.zeros((ARMS, 3))
        self.before = np.zeros(ARMS, bool)  # which arms gripped at the sample before the window
        self.largest = {"rotor_error_max": -np.inf, "closure_error_max": -np.inf}
        self.fewest, self.gamma = ARMS, [np.inf, -np.inf]
        self.regrips = _regrips(traj)  # (release, grip, the grip's sample)
        self.events: dict[int, dict] = {}
        self.tail: dict[str, np.ndarray] = {}  # the window before's last two samples of the tips and rotor

    def add(self, traj, rec, series: dict) -> dict:
        lo, hi = self.lo, self.lo + rec.t.size  # windows come in order, from the first sample
        engaged = gripping(rec)
        gamma = rec.q[:, ARMS:]
        error, closure = _rotor_errors(traj, rec, engaged, self.anchor, self.before)
        self.before = engaged[-1]
        held = gamma[engaged]
        for name, values in (("rotor_error_max", error), ("closure_error_max", closure)):
            self.largest[name] = max(self.largest[name], float(values.max()))
        self.fewest = min(self.fewest, int(engaged.sum(axis=1).min()))
        if held.size:
            self.gamma = [min(self.gamma[0], float(held.min())), max(self.gamma[1], float(held.max()))]
        self._snaps(rec, lo, hi)
        self.lo = hi
        # gamma and rotor_quat as views of the recording, which the run keeps anyway, not copies
        return {"gamma": gamma, "engaged": engaged, "rotor_quat": rec.sensors["rotor_quat"],
                "rotor_error": error, "closure_error": closure}

    def _snaps(self, rec, lo: int, hi: int) -> None:
        """The re-grips whose samples either side of the grip are the window's (or the last two before it)."""
        names = [f"em{arm + 1}_tip" for arm in range(ARMS)] + ["rotor_quat"]
        rows = {name: np.concatenate([self.tail[name], rec.sensors[name]]) if self.tail else rec.sensors[name]
                for name in names}
        first = lo - len(rows["rotor_quat"]) + rec.t.size  # the sample of rows' first row
        for i, (release, grip, k) in enumerate(self.regrips):
            if lo - 1 <= k <= hi - 2:
                tip = rows[f"em{grip.detail['arm']}_tip"][k - 1 - first:k + 2 - first]
                self.events[i] = _regrip_event(release, grip, tip, rows["rotor_quat"][k - first])
        self.tail = {name: v[-2:].copy() for name, v in rows.items()}

    def finish(self) -> tuple[dict, list[dict]]:
        report = {**self.largest, "fewest_gripping": self.fewest,
                  "gripping_gamma": {"min": self.gamma[0], "max": self.gamma[1]},
                  "switch_events": [self.events[i] for i in range(len(self.regrips))]}
        return report, []


def _rotor_errors(traj, rec, engaged: np.ndarray, anchor: np.ndarray, before: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The rotor's error (angle from the planned orientation) and the closure error (the largest distance, m, a
    gripping EM's tip has moved on the rotor since it gripped), (N,) each, CHUNK samples at a time. `anchor`: each
    arm's tip in the rotor's frame at its last grip, updated in place; `before`: which arms gripped just before."""
    quat, planned = rec.sensors["rotor_quat"], traj.series["rotor_quat_ref"]
    error, closure = np.empty(rec.t.size), np.zeros(rec.t.size)
    grips = engaged & ~np.concatenate([before[None], engaged[:-1]])  # the rows where each arm grips
    for a in range(0, rec.t.size, CHUNK):
        b = min(a + CHUNK, rec.t.size)
        rot = quat_to_matrix(quat[a:b])
        error[a:b] = rotation_angle(quat_to_matrix(planned[a:b]), rot)
        for arm in range(ARMS):
            on_rotor = np.einsum("nji,nj->ni", rot, rec.sensors[f"em{arm + 1}_tip"][a:b])  # R^T tip
            since = np.maximum.accumulate(np.where(grips[a:b, arm], np.arange(b - a), -1))  # -1: before the chunk
            gripped = on_rotor[np.maximum(since, 0)]
            gripped[since < 0] = anchor[arm]
            drift = np.linalg.norm(on_rotor - gripped, axis=1)
            closure[a:b] = np.maximum(closure[a:b], np.where(engaged[a:b, arm], drift, 0.0))
            anchor[arm] = gripped[-1]
    return error, closure


def _regrips(traj) -> list[tuple]:
    """One (release, grip, the grip's sample) a re-grip (not the initial grips), the sample kept off the ends."""
    found, releases = [], {}
    for sw in traj.switches:
        arm = sw.detail["arm"]
        if not sw.active:
            releases[arm] = sw
        elif arm in releases:
            k = int(np.clip(np.searchsorted(traj.t, sw.t - 1e-9), 1, len(traj.t) - 2))
            found.append((releases[arm], sw, k))
    return found


def _regrip_event(release, grip, tip: np.ndarray, quat: np.ndarray) -> dict:
    """A re-grip's event: the arm, the points, its snap (the second difference of `tip` at the samples before, at
    and after the grip) and its offset (the tip from the planned contact point; `quat`: the rotor then)."""
    arm = grip.detail["arm"]
    jump = float(np.linalg.norm(tip[2] - 2 * tip[1] + tip[0]))
    held = grip.detail.get("point")  # the point gripped (rotor frame), or the paper's candidate by its letter
    rot = quat_to_matrix(quat)[0]
    point = rot @ (np.asarray(held) if held is not None else POINTS[arm - 1, "abc".index(grip.detail["to_point"])])
    point = point * RADIUS
    return {"t_start": release.t, "t_end": grip.t, "kind": "switch",
            "detail": {"arm": arm, "from_point": grip.detail["from_point"], "to_point": grip.detail["to_point"],
                       "contact_jump": jump, "grip_offset": float(np.linalg.norm(tip[1] - point))}}


def paint(model, rec, row: int) -> None:
    """Colour each EM by its state in this frame: green while it grips, grey while it is free."""
    for i in range(ARMS):
        on = rec.eq_active[f"grip{i + 1}"][row]
        model.geom(f"em{i + 1}").rgba = _GRIPPING_RGBA if on else _FREE_RGBA


def plots(traj, rec, result) -> dict[str, Figure]:
    """gamma of every arm against time with its switches (paper 001's Fig. 11 is arm 1's)."""
    from simbench.api.panels import time_panels

    engaged = gripping(rec)
    fig, axes = time_panels(ARMS, 8, 7)
    axes = axes[:, 0]
    for arm, ax in enumerate(axes):
        _plot_gamma(ax, rec, arm, engaged[:, arm], result.extra["switch_events"])
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title("gamma of each arm (red: re-grips; dotted: the 10-170 deg band)", y=1.0)
    axes[-1].set_xlabel("time (s)")
    return {"gamma": fig}


def _plot_gamma(ax, rec, arm: int, engaged: np.ndarray, switch_events: list[dict]) -> None:
    """Arm `arm`'s gamma (deg): green while it grips, grey while it swings, re-grips red, eq. 45's band dotted."""
    g = np.rad2deg(rec.q[:, ARMS + arm])
    ax.plot(rec.t, np.where(engaged, g, np.nan), color="tab:green", lw=1.2, label="gripping")
    ax.plot(rec.t, np.where(engaged, np.nan, g), color="tab:gray", lw=1.0, label="swinging")
    for bound in np.rad2deg(GAMMA_BAND):
        ax.axhline(bound, color="k", ls=":", lw=0.8)
    for e in switch_events:
        if e["detail"]["arm"] == arm + 1:
            ax.axvline(e["t_end"], color="tab:red", lw=0.8)
    ax.set_ylabel(f"gamma{arm + 1} (deg)")
    ax.set_ylim(-5, 185)
    ax.grid(alpha=0.3)
