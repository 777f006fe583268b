"""The scenario: a YAML document read into a validated Scenario (document), its field types (schema), the reading
of its files (validation) and the robot a scenario names (robot_mapping).

Imports core, maths, api and robots.
"""

from simbench.scenario.document import Scenario, Sim, Thresholds, Timing, as_scenario, load_scenario, parse_scenario

__all__ = ["Scenario", "Sim", "Thresholds", "Timing", "as_scenario", "load_scenario", "parse_scenario"]
