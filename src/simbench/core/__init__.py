"""Run-time infrastructure every stage uses: errors and their one-line messages, the run's budget, the compiled
model (plant), MuJoCo's warnings, interrupts, forked workers, atomic writes and output folders, shipped resources.

Imports nothing of simbench outside this folder.
"""
