"""python -m simbench: see simbench.cli. The current folder is taken off sys.path (as pip does), so that a stray
file there (a yaml.py) is not imported in place of a dependency."""

import os
import sys

if not sys.flags.safe_path and sys.path and sys.path[0] in ("", os.getcwd()):
    del sys.path[0]

from simbench.cli import main  # noqa: E402

raise SystemExit(main())
