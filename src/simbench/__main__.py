"""python -m simbench: see simbench.cli. The current folder is taken off sys.path (as pip does), so that a stray
file there (a yaml.py) is not imported in place of a dependency. Ctrl-C before main answers it (while the command
line's modules are imported) ends as one during the command: one line, exit 130."""

import os
import signal
import sys

if not sys.flags.safe_path and sys.path and sys.path[0] in ("", os.getcwd()):
    del sys.path[0]

try:
    from simbench.cli import main

    code = main()
except KeyboardInterrupt:
    print("interrupted", file=sys.stderr)
    code = 128 + signal.SIGINT
raise SystemExit(code)
