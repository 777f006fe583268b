"""Paper 003's trajectory optimisation for the Agile Eye: a 4-5-6-7 joint path bent around obstacles and
type 2 singularities by smooth bumps whose parameters SLSQP finds.

  1. The start and goal orientations give the base angles by IK in the chosen working mode; each joint goes
     theta_j(t) = theta_j_init + (theta_j_final - theta_j_init) S(t / T) with S = 35 tau^4 - 84 tau^5
     + 70 tau^6 - 20 tau^7 (eqs. 8-10): zero velocity, acceleration and jerk at both ends.
  2. Along the path the platform orientation is estimated (by the learnt FK, as the paper does, or exactly),
     and so the clearance from every obstacle (a ball of orientations: geodesic angle to its centre minus its
     radius) and from the type 2 singular curves (the angle between some v_i and u_i); a floor on the KCI may
     be set too, since near the singular curves the platform magnifies joint errors by about 1 / KCI.
  3. Where a clearance falls below its margin, a bump is added over a window of T* seconds centred on the
     worst sample: theta_j += c_j L b((t - t0) / T*), b(tau) = 256 tau^4 (1 - tau)^4, whose value and first
     three derivatives vanish at both ends of the window (the role of S*(tau*) in eqs. 11-12, whose printed
     form is lost). (c_1, c_2, c_3) = (alpha, beta, gamma) is a unit direction and L the amplitude (rad);
     scipy's SLSQP chooses them to maximise the path's mean KCI less a small cost on L, subject to every
     clearance staying above its margin over the whole path (sections 6-7). SLSQP is given the gradients
     analytically (project issue 14): the KCI's and each clearance's partial derivatives in the base angles and
     in the platform's rotation (agile_eye.kci_partials, axis_gap_partials, _angle_partial), pulled back through
     the estimate's own derivative (the network's by reverse mode, the exact FK's A^-1 B) and the bump.
  4. Repeat for the next violation, up to max_windows; then check the result with the exact FK.

Two additions of ours (project issue 19):
  5. Where the bent path still breaks a margin (a plain path across a type 2 curve is rarely saved by windows:
     they are too short to go round it), a global search in SO(3) (so3_search: RRT-Connect, shortcuts, corners
     rounded) finds an orientation path that keeps every margin; it is timed by the same 4-5-6-7 law over the
     scenario's duration, by its geodesic angle, and the joints follow it by IK in the task's working mode. No
     window or SLSQP start is begun once half of task.avoidance.time_budget is spent; the search gets the rest
     of the budget, and at least half of it (a slower machine may so stop with fewer windows). If no path
     keeps the margins, the planner refuses (RunError) naming the margins and the best clearances found, unless
     task.accept_margin_violation hands over the best path anyway, with warnings and, where its platform
     passes the type 2 singular surface or ends away from the goal (by the exact FK), the violations
     singular_crossing and goal_missed (simbench.verdict), so that such a run is never `ok` (a margin
     short of that, an obstacle's or the KCI's, stays a warning: the verdict has no kind for it).
     One assembly mode throughout: det A (with theta the IK of R in a fixed working mode) has one sign over all
     of SO(3) off the singular curves (IK is continuous there, det A vanishes only on the curves, and the curves
     do not cut SO(3) apart), so a path that keeps away from the curves keeps the start's assembly mode; the
     final plan is checked for it all the same (det A's sign along the exact FK of the sampled joints).
  6. The plan carries every joint of the closed chain, the passive ones included, assembled at the start
     orientation (JointTrajectory.initial): the robot's own assembly picks the FK solution nearest home, which
     for most start orientations is another assembly mode.
"""

from simbench.planners.avoidance_4567.path import Plan, Window, bump
from simbench.planners.avoidance_4567.planner import PLANNER, Avoidance4567
from simbench.planners.avoidance_4567.task import Avoidance, Obstacle, Task, clearances, margins
from simbench.planners.avoidance_4567.windows import optimise

__all__ = ["PLANNER", "Avoidance", "Avoidance4567", "Obstacle", "Plan", "Task", "Window", "bump", "clearances",
           "margins", "optimise"]
