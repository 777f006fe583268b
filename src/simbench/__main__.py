"""python -m simbench: see simbench.cli."""

from simbench.cli import main

raise SystemExit(main())
