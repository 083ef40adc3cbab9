"""How a command is interrupted: Ctrl+C, SIGTERM and SIGHUP stop it as Ctrl+C would.

`install_interruptions` makes `interrupt` the handler of each of `INTERRUPTIONS` that is not
ignored when the program starts (``nohup`` ignores SIGHUP so that a run outlives the terminal,
and a shell ignores SIGINT in the jobs it starts in the background). `interrupt` raises
`KeyboardInterrupt` carrying the signal's name, so clean-up runs, and `aborted` prints the one
line ``mirror-avatar: aborted (SIGTERM)`` and returns exit code 130. This module imports nothing
of the package, so the console script installs the handlers before anything heavy is imported.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from types import FrameType

INTERRUPT_RETRY = 0.05
"""Seconds after which an interruption that arrived while compiling is delivered again."""

INTERRUPTIONS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""Signals that stop a command as Ctrl+C would (its clean-up runs, exit code 130)."""

ABORTED = 130
"""Exit code of an interrupted command."""


def _compiling() -> bool:
    """Whether numba's compiler lock is held (numba is not imported for the question)."""
    lock_module = sys.modules.get("numba.core.compiler_lock")
    return lock_module is not None and lock_module.global_compiler_lock.is_locked()


def interrupt(signum: int, frame: FrameType | None) -> None:
    """Signal handler: stop the program as Ctrl+C would, so its clean-up runs.

    The `KeyboardInterrupt` carries the signal's name. Not while this thread compiles (it
    holds numba's compiler lock): an exception raised inside the compiler leaves LLVM objects
    half made, and the process crashes when they are freed. The signal is then sent again after
    `INTERRUPT_RETRY`, until compiling is done.
    """
    if _compiling():
        again = threading.Timer(INTERRUPT_RETRY, os.kill, (os.getpid(), signum))
        again.daemon = True
        again.start()
        return
    raise KeyboardInterrupt(signal.Signals(signum).name)


def install_interruptions() -> list[signal.Signals]:
    """Handle `INTERRUPTIONS` with `interrupt`, except those ignored; return those handled."""
    handled = []
    for signum in INTERRUPTIONS:
        if signal.getsignal(signum) is signal.SIG_IGN:
            continue
        signal.signal(signum, interrupt)
        handled.append(signum)
    return handled


def aborted(stop: BaseException) -> int:
    """Print the one line of an interrupted command, naming the signal if one arrived.

    ``stop`` is the `KeyboardInterrupt` of `interrupt`, or click's ``Abort`` raised from it.
    """
    name = str(stop.__cause__ or stop)
    reason = f" ({name})" if name.startswith("SIG") else ""
    print(f"mirror-avatar: aborted{reason}", file=sys.stderr, flush=True)
    return ABORTED
