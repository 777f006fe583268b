"""simbench benchmarks: python -m benchmarks.run rewrites BENCHMARKS.md."""

import os

# Rendering without a display (set before any benchmark imports MuJoCo).
os.environ.setdefault("MUJOCO_GL", "egl")
