"""A planar 3R arm (`robot.ROBOT`) and a damped-least-squares line planner (`planner.PLANNER`) for simbench, made
known to it by the entry points in pyproject.toml."""
