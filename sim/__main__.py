"""``python -m sim``: see :mod:`sim.runs.cli`."""

import sys

from sim.runs.cli import main

sys.exit(main())
