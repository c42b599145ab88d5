"""A Ctrl-C while the ``bullet-dlo`` command is still loading its libraries: one line, not a traceback.

The command line turns a Ctrl-C during a run into one line and exit code 130 itself; before
it runs, Python, NumPy, SciPy and Numba take about a second to import, and an interrupt there
would print their import traceback. :func:`quiet_interrupt` makes Python print one line for an
interrupt nobody caught; Python still exits with 130 (killed by SIGINT).
"""
from __future__ import annotations

import sys

MESSAGE = "interrupted (Ctrl-C) while bullet-dlo was starting: nothing was run or written"


def quiet_interrupt() -> None:
    """Report an uncaught KeyboardInterrupt as one line on stderr (other exceptions as before)."""
    previous = sys.excepthook

    def hook(kind, value, tb) -> None:
        if issubclass(kind, KeyboardInterrupt):
            print(MESSAGE, file=sys.stderr)
        else:
            previous(kind, value, tb)

    sys.excepthook = hook


def is_command_line() -> bool:
    """Whether this process is the ``bullet-dlo`` command (its console script)."""
    return bool(sys.argv) and sys.argv[0].endswith("bullet-dlo")
