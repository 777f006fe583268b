"""The simulation stage: the plant fitted to the plan, its closed loop (servo, computed torque, a policy) stepped in
MuJoCo with the plan's switches, and what it records.

Imports the stages before it (core, maths, api, robots, scenario, planners), never analysis, outputs or commands.
"""
