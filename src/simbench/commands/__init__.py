"""What a user runs: one run end to end (pipeline), sweeps, compare, reproduce, bench and inspect-arm.

Imports every stage; nothing but the command line, the package's face and simbench.env imports it.
"""
