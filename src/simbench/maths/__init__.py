"""Geometry and time laws the stages share: vectors and rotations, the paths' segments, a point's distance from a
sampled path, and the time laws s(t).

Imports only simbench.core.
"""
