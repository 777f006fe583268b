"""Paper 001's "Round Robin" operation of the RSMG (section 4, Fig. 10): unlimited rotor motion by re-gripping.

The rotor's commanded orientation R(t) is given: turns about a fixed axis, or a tumble (a spin about a rotor
axis while that axis precesses), on a time law. Each arm holds one of its three candidate contact points; while
it does, its base angle and gamma follow from the IK of the point's current direction (eqs. 12-23). An arm must
let go before its gamma leaves (10, 170) deg (eq. 45, less `gamma_margin`), and the arms gripping the rotor
keep their Jacobian A far from losing rank over the whole schedule: while one arm swings (|det A| of the three
holding), and while all four grip (the largest 3 x 3 minor, eqs. 36-39: four gripping arms can lose rank too,
and then no swing rescues them, since each three of them is as weak). Eq. 46 puts rank loss at |det A| < 0.01;
the schedule keeps this measure >= `det_a_min`, ours, since near 0.01 the rotor is held so loosely that it
drifts by degrees. A motion for which no schedule keeps both is refused (RunError). Its
next point, with `contacts: fixed` (the paper's scheme), is the next candidate in round-robin order (a -> b -> c
-> a) whose gamma is inside the band when the arm gets there; with `contacts: general` (the default, issue 16)
any point of the rotor the arm reaches, the one that keeps its gamma inside the band longest and the holding arms'
|det A| highest over the coming motion (planners.rsmg_contacts), with the floor on |det A| rising with the
rotor's speed and every hold and swing inside the joints' speed limits. A motion general contacts cannot follow
is refused before it is simulated, with the limit that binds (the joints' speed, the time a re-grip takes, or
|det A| and the band), its numbers, and a longer duration over which the same motion is scheduled. While an arm
swings (a quintic in theta and gamma, matching position, speed and acceleration at both ends) the other three arms
hold the rotor, and only one arm swings at a time, so at least three always grip. A swing ends `approach_time`
before the grip: the arm then
follows its next point, not yet gripping, so that its servos settle and the weld goes on where the plan has the
point (ours: the paper switches the electromagnet on when the arm arrives; without the approach a long fast
swing ends a millimetre or two off, and the gripping arms then fight over the rotor).

Closing the loop at each grip (ours; `regrip_feedback`, on by default): a weld holds the EM wherever it touches,
so an arm that grips while the rotor is off its command grips a point off the candidate, and its planned hold
(the IK of the candidate) then pulls against the other arms. Open loop, the paper's way, these offsets add up
grip after grip: in ten minutes of tumbling the rotor drifted by degrees, then tens of degrees, then was lost.
With feedback, when an arm grips, its hold is re-solved for the point it really holds, found from the rotor's
orientation (which a controller has from the gripping arms' encoders by the direct kinematics, eq. 32), so
that every gripping arm pulls the rotor towards its command; the change is eased in over EASE and out over
the next swing.

Switches are planned ahead: with the gripping arms' exits e_1 <= e_2 <= ... (the times their gammas leave the
band less a margin), the first arm lets go by min_k (e_k - k T_swing), so that every arm can swing in turn
before its exit; and by e_A - T_swing, e_A the time the four arms' A would fall under `det_a_min`, so that one
of them (any) holds another point by then.
"""

from simbench.planners.round_robin.planner import PLANNER, RoundRobin
from simbench.planners.round_robin.schedule import schedule
from simbench.planners.round_robin.search import Hold
from simbench.planners.round_robin.task import Motion, Task

__all__ = ["PLANNER", "Hold", "Motion", "RoundRobin", "Task", "schedule"]
