"""The round-robin Planner: the grips scheduled, then every arm solved at every control sample."""

from __future__ import annotations

import numpy as np

from simbench.api import Planner
from simbench.api.trajectory import JointTrajectory, control_grid
from simbench.core.errors import RunError
from simbench.planners.round_robin.checks import refusal
from simbench.planners.round_robin.feedback import RegripFeedback
from simbench.planners.round_robin.paths import engaged_arms, grip_switches, joint_paths, joint_rates, rotor_references
from simbench.planners.round_robin.schedule import Stuck, schedule_grips
from simbench.planners.round_robin.task import Task
from simbench.robots import rsmg


class RoundRobin(Planner):
    """Paper 001: RSMG rotor motion by round-robin re-gripping of four electromagnet arms."""

    name = "round_robin"
    description = "paper 001: RSMG rotor motion by round-robin re-gripping of four electromagnet arms"
    task = Task
    robots = ("rsmg",)
    seconds_per_sample = 13e-6  # the search with general contacts, beyond budget.py's _SAMPLE_SECONDS

    def plan(self, scenario, robot, dt: float) -> JointTrajectory:
        """Schedule the grips and solve every arm at every control sample."""
        task = scenario.task
        law = scenario.timing.law_fn()
        try:
            sched = schedule_grips(task, law, scenario.timing.hold)
        except Stuck as stuck:
            if task.contacts == "fixed":
                raise
            raise RunError(refusal(task, law, scenario.timing.hold, stuck)) from None
        t = control_grid(law.duration, scenario.timing.hold, dt)
        sched.contacts.forget()  # the search's caches go before the per-sample arrays come
        s = law(t, order=0)[0]
        q_ref = joint_paths(t, sched)
        switches = grip_switches(sched.holds, sched.grid, sched.contacts)
        sched.contacts.forget()  # the paths' IK: its cached blocks refer back to the contacts, which then go at once
        holds, grid, count = sched.holds, sched.grid, sched.contacts.count
        del sched  # the contacts and the rotor's axes on the schedule grid go before the references that remain come
        engaged = engaged_arms(t, holds, grid)
        feedback = RegripFeedback(task.motion, s, q_ref, holds, grid, dt, round(task.swing_time / dt)) \
            if task.regrip_feedback else None
        tool_ref, quat = rotor_references(task.motion, s)
        info = {
            "method": "paper 001: round-robin re-gripping (section 4)",
            "design": {"alpha": rsmg.ALPHA, "beta": rsmg.BETA, "arms": rsmg.ARMS, "candidates": count},
            "contacts": task.contacts,
            "grips": len(holds) - rsmg.ARMS,
            "fewest_gripping": int(engaged.sum(axis=1).min()),
        }
        return JointTrajectory(t=t, s=s, q_ref=q_ref, qd_ref=joint_rates(q_ref, dt), tool_ref=tool_ref, info=info,
                               switches=switches, series={"rotor_quat_ref": quat, "engaged_ref": engaged},
                               initial={"rotor": quat[0].tolist()}, feedback=feedback)


    def random_task(self, robot, random: np.random.RandomState) -> dict | None:
        """A random rotor motion with general contacts (rsmg_contacts.random_motion)."""
        from simbench.planners.rsmg_contacts import random_motion

        return random_motion(random)


PLANNER = RoundRobin()
