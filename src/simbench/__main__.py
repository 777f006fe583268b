"""python -m simbench: see simbench.cli. The current folder is taken off sys.path (as pip does), so that a stray
file there (a yaml.py) is not imported in place of a dependency. Ctrl-C before main answers it (while the command
line's modules are imported, held back until they are) ends as one during the command: one line, exit 130."""

import os
import signal
import sys

if not sys.flags.safe_path and sys.path and sys.path[0] in ("", os.getcwd()):
    del sys.path[0]

try:
    from simbench.core import interrupts

    with interrupts.held_back():  # an extension module being imported would turn Ctrl-C into an ImportError
        from simbench.cli import exit_with, main
    code = main()
except KeyboardInterrupt:
    print("interrupted", file=sys.stderr)
    raise SystemExit(128 + signal.SIGINT) from None
exit_with(code)
