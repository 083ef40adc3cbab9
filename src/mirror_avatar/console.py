"""The ``mirror-avatar`` console script: interruption handled from the first instant.

`run` installs the signal handlers (`mirror_avatar.common.interruptions`) before anything heavy is
imported (the command line pulls in numba, SciPy and the commands, seconds of work on a busy
machine), so a SIGTERM that arrives while the program starts ends it as one arriving later does:
the line ``mirror-avatar: aborted (SIGTERM)`` and exit code 130. A signal that is ignored when
the program starts stays ignored.
"""

from __future__ import annotations

import sys

from mirror_avatar.common.interruptions import aborted, install_interruptions


def run() -> None:
    """Console-script entry point: install the handlers, then run the command line and exit."""
    install_interruptions()
    try:
        from mirror_avatar.cli import main
    except KeyboardInterrupt as stop:
        sys.exit(aborted(stop))
    sys.exit(main())
