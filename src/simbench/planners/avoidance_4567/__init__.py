"""Paper 003's trajectory optimisation for the Agile Eye: a 4-5-6-7 joint path bent around obstacles and
type 2 singularities by smooth bumps whose parameters SLSQP finds.

  1. Base angles by IK in the working mode; theta_j(t) = theta_j_init + (theta_j_final - theta_j_init) S(t / T),
     S = 35 tau^4 - 84 tau^5 + 70 tau^6 - 20 tau^7 (eqs. 8-10).
  2. Along the path, the estimated orientation (learnt FK, as the paper, or exact) gives the clearances from
     obstacles (balls of orientations) and type 2 singular curves, and optionally the KCI.
  3. Where a clearance falls below its margin, a window of T* centred on the worst sample adds
     theta_j += c_j L b((t - t0) / T*), b(tau) = 256 tau^4 (1 - tau)^4 (the role of S*(tau*) in eqs. 11-12, whose
     printed form is lost); SLSQP picks the unit direction (alpha, beta, gamma) and L to maximise the mean KCI
     less a cost on L, every clearance kept (sections 6-7), with analytic gradients.
  4. Repeat up to max_windows; check the result with the exact FK.

Ours: 5. where windows fail, a global search in SO(3) (so3_search) within the rest of time_budget; none found: a
RunError, unless accept_margin_violation hands over the best path with warnings (and singular_crossing or
goal_missed violations). A path off the singular curves keeps the start's assembly mode (det A has one sign there);
the plan is checked for it. 6. The plan carries the passive joints too, assembled at the start orientation
(JointTrajectory.initial), as the robot's own assembly may pick another mode.
"""

from simbench.planners.avoidance_4567.path import Plan, Window, bump
from simbench.planners.avoidance_4567.planner import PLANNER, Avoidance4567
from simbench.planners.avoidance_4567.task import Avoidance, Obstacle, Task, clearances, margins
from simbench.planners.avoidance_4567.windows import optimise

__all__ = ["PLANNER", "Avoidance", "Avoidance4567", "Obstacle", "Plan", "Task", "Window", "bump", "clearances",
           "margins", "optimise"]
