"""Metrics and events from a Recording: how well the tool followed the plan, and what it came near.

Tracking: joint errors; the tool's distance from the planned path (the polyline of the planned tool points),
its lag along the path, and its error against the time-indexed reference, as per-sample series; the metrics
(simbench.api.Metric, the shipped `tracking` among them: simbench.analysis.tracking) reduce them to figures. Events
(simbench.api.Event):
  singularity_events  spans where the recorded configuration lies near one of the robot's singular sets;
  limit_events        `joint_limit` (the plan asks for a value beyond a joint's range), `at_limit` (the joint
                      sits at a limit), `reference_jump` (the plan steps farther in one sample than the joint's
                      speed limit allows in ten: a discontinuity), `velocity_limit` (the plan is faster than
                      the joint can go) and `actuator_saturation` (a joint's actuator at its force bound: the
                      motor cannot give what tracking the plan takes).

Its modules: analyser (Analysis, analyse, Analyser), tangents
(the path's direction, for the lag) and limit_events (the plan's and the joints' limit events, the plan's jumps);
the shipped metrics (tracking, singularity_handling), the verdict and the bench's scores.

Imports the stages before it (core to physics), never outputs or commands.
"""

from simbench.analysis.analyser import Analyser, Analysis, analyse
from simbench.analysis.limit_events import plan_limit_events
from simbench.analysis.tangents import along_path
from simbench.maths.path_distance import deviation_near_reference, path_deviation

__all__ = ["Analyser", "Analysis", "along_path", "analyse", "deviation_near_reference", "path_deviation",
           "plan_limit_events"]
