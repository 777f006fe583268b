"""Why general contacts cannot follow a motion: the refusal's words and numbers, found by scheduling the same
motion with a limit lifted or over a longer duration."""

from __future__ import annotations

import numpy as np

from simbench.core.errors import RunError
from simbench.maths.timing import TimeLaw
from simbench.planners.round_robin.paths import joint_paths
from simbench.planners.round_robin.schedule import Stuck, grid_orientations, schedule_grips, unkept_limits
from simbench.planners.round_robin.search import STEP
from simbench.planners.round_robin.task import Task
from simbench.planners.rsmg_contacts import SPEED_SHARE, angular_speed
from simbench.robots import rsmg

_SLOWER = (1.25, 1.5, 2.0, 3.0, 4.0)  # a refused motion's durations tried, as multiples of the task's


def refusal(task: Task, law: TimeLaw, hold: float, stuck: Stuck) -> str:
    """Why general contacts cannot follow the motion: where the search got furthest, which limit binds (`_cause`),
    and the shortest longer duration over which it is scheduled."""
    speed = angular_speed(grid_orientations(task, law, hold)[1], STEP)  # rad/s on the schedule grid
    step = min(stuck.step, speed.size - 1)
    head = (f"round robin (general contacts): no schedule follows this motion, which turns the rotor at up to "
            f"{np.rad2deg(speed.max()):.0f} deg/s")
    if step > 0:  # where the search got furthest
        where = str(stuck).removeprefix("round robin: ").split("; no schedule")[0]
        head += f" ({where}, the rotor turning at {np.rad2deg(speed[step]):.0f} deg/s there)"
    for factor in _SLOWER:
        slower = TimeLaw(law.name, law.duration * factor, law.accel_fraction)
        try:
            schedule_grips(task, slower, hold)
        except RunError:
            continue
        peak = np.rad2deg(speed.max()) / factor  # the same path on a law stretched in time
        works = (f"the same motion over timing.duration = {slower.duration:.3g} s (up to {peak:.0f} deg/s) is "
                 "scheduled")
        break
    else:
        works = f"nor is the same motion over {_SLOWER[-1]:g} times the duration"
    return f"{head}; {_cause(task, law, hold)}; {works}"


def _cause(task: Task, law: TimeLaw, hold: float) -> str:
    """Which limit binds, found by lifting each: the joints' speed, the re-grips' time (swings twice as fast), or
    neither (the band and |det A| themselves)."""
    try:
        sched = schedule_grips(task, law, hold, speed_share=np.inf)
    except RunError:
        pass
    else:
        qd = np.abs(np.gradient(joint_paths(sched.grid, sched), STEP, axis=0))
        row, joint = np.unravel_index(np.argmax(qd), qd.shape)
        if qd[row, joint] >= SPEED_SHARE * rsmg.QD_MAX[joint]:
            return (f"the joints' speed limit binds: with it lifted the motion is scheduled, asking "
                    f"{rsmg.JOINTS[joint]} for {qd[row, joint]:.1f} rad/s at t = {sched.grid[row]:.2f} s, more than "
                    f"the {SPEED_SHARE:.0%} of its {rsmg.QD_MAX[joint]:.1f} rad/s limit that holds and swings keep to")
    quick = task.model_copy(update={"swing_time": task.swing_time / 2, "approach_time": task.approach_time / 2})
    swing = task.swing_time + task.approach_time
    try:
        schedule_grips(quick, law, hold, speed_share=np.inf)
    except RunError:
        return (f"neither the joints' speed nor the re-grips' time binds alone: "
                f"{unkept_limits(task, 'no set of points')} with one arm re-gripping at a time")
    return (f"re-gripping binds: the points the arms can hold leave the gamma band (eq. 45) before the arms, one at "
            f"a time and {swing:.2f} s a re-grip (swing_time + approach_time), have re-gripped in turn; at "
            f"{swing / 2:.2f} s a re-grip (and joints without a speed limit) it is scheduled")
