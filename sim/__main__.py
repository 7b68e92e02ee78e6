"""``python -m sim``: see :mod:`sim.runs.cli`."""

import os
import sys

from sim.runs.cli import main

try:
    code = main()
    sys.stdout.flush()
except BrokenPipeError:
    # The reader of stdout has gone (``| head``): the run's files are written; say nothing more, and
    # point stdout at devnull so the interpreter's final flush does not raise again.
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    code = 141  # 128 + SIGPIPE, as a shell reports a command killed by it
sys.exit(code)
