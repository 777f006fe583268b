"""Paper 001's "Round Robin" operation of the RSMG (section 4, Fig. 10): unlimited rotor motion by re-gripping.

The rotor's orientation R(t) is commanded (turns, or a tumble). A holding arm's theta and gamma follow from the IK
of its point (eqs. 12-23); it must let go before gamma leaves eq. 45's band less `gamma_margin`, and the gripping
arms keep their A far from rank loss (|det A| of three while one swings, the largest 3 x 3 minor while four grip;
eqs. 36-39, 46) at >= `det_a_min` (ours: near eq. 46's 0.01 the rotor drifts by degrees). Its next point is the
next candidate in round-robin order (`contacts: fixed`) or the best of any point (`general`, rsmg_contacts). One
arm swings at a time (a quintic), so three always grip; none such schedule: refused (RunError, checks.refusal).

Ours: a swing ends `approach_time` before the grip, following the next point so the servos settle where the plan
has it; and with `regrip_feedback` each grip's hold is re-solved for the point really gripped (from the rotor's
orientation, eq. 32), since open-loop offsets add up grip after grip until the rotor is lost.

Switches are planned ahead: with the gripping arms' exits e_1 <= e_2 <= ..., the first lets go by
min_k (e_k - k T_swing); and by e_A - T_swing, where the four arms' A would fall under `det_a_min`.
"""

from simbench.planners.round_robin.planner import PLANNER, RoundRobin
from simbench.planners.round_robin.schedule import schedule
from simbench.planners.round_robin.search import Hold
from simbench.planners.round_robin.task import Motion, Task

__all__ = ["PLANNER", "Hold", "Motion", "RoundRobin", "Task", "schedule"]
