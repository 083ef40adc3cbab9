"""How a command is interrupted: Ctrl+C, SIGTERM and SIGHUP stop it as Ctrl+C would.

`install_interruptions` makes `interrupt` the handler of each of `INTERRUPTIONS` that is not
ignored when the program starts (``nohup`` ignores SIGHUP so that a run outlives the terminal,
and a shell ignores SIGINT in the jobs it starts in the background). `interrupt` raises
`KeyboardInterrupt` carrying the signal's name, so clean-up runs, and `aborted` prints the one
line ``mirror-avatar: aborted (SIGTERM)`` and returns exit code 130. This module imports nothing
of the package, so the console script installs the handlers before anything heavy is imported.

An event loop is run by `run_interruptible`: there the loop takes the signals, and an
interruption cancels the loop's main coroutine, so that its clean-up runs as the cancellation
unwinds and no task is left to fail at the loop's close.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Coroutine
from types import FrameType
from typing import Any, TypeVar

T = TypeVar("T")

INTERRUPT_RETRY = 0.05
"""Seconds after which an interruption that arrived inside numba is delivered again."""

INTERRUPTIONS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""Signals that stop a command as Ctrl+C would (its clean-up runs, exit code 130)."""

ABORTED = 130
"""Exit code of an interrupted command."""


def _compiling() -> bool:
    """Whether this thread holds numba's compiler lock (numba is not imported for the question)."""
    lock_module = sys.modules.get("numba.core.compiler_lock")
    return lock_module is not None and lock_module.global_compiler_lock.is_locked()


def _inside_numba(frame: FrameType | None) -> bool:
    """Whether a frame of numba's own Python code is on the stack from ``frame`` down."""
    numba = sys.modules.get("numba")
    if numba is None or numba.__file__ is None:
        return False
    package = os.path.dirname(numba.__file__) + os.sep
    while frame is not None:
        if frame.f_code.co_filename.startswith(package):
            return True
        frame = frame.f_back
    return False


_DUE_AGAIN: set[int] = set()
"""The signals held back and not yet sent again."""


def _send_again(signum: int) -> None:
    """Send ``signum`` to this process after `INTERRUPT_RETRY`, unless it is already due.

    One retry at a time: signals arriving while one is due join it, so a burst of them starts
    one timer thread, and a signal landing while the timer starts is not handled inside it.
    """
    if signum in _DUE_AGAIN:
        return
    _DUE_AGAIN.add(signum)

    def send() -> None:
        _DUE_AGAIN.discard(signum)
        os.kill(os.getpid(), signum)

    again = threading.Timer(INTERRUPT_RETRY, send)
    again.daemon = True
    again.start()


def interrupt(signum: int, frame: FrameType | None) -> None:
    """Signal handler: stop the program as Ctrl+C would, so its clean-up runs.

    The `KeyboardInterrupt` carries the signal's name. Not inside numba: while this thread
    compiles (it holds numba's compiler lock), an exception leaves LLVM objects half made, and
    the process crashes when they are freed; while numba's Python code converts the arguments of
    a call to compiled code (a compiled function given as an argument is looked up in Python),
    numba passes on a half-converted argument and the call fails with an unrelated error. The
    signal is then sent again after `INTERRUPT_RETRY` (`_send_again`), until numba is done.
    """
    if signum in _DUE_AGAIN or _compiling() or _inside_numba(frame):
        _send_again(signum)
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


def run_interruptible(main: Coroutine[Any, Any, T]) -> T:
    """Run ``main`` in a new event loop; an interruption cancels it, then stops the program.

    `interrupt` would raise `KeyboardInterrupt` wherever the loop happens to be (waiting for
    its sockets, or in one task's step), and the tasks left behind would be cancelled at the
    loop's close, their failures printed as tracebacks. Here each of `INTERRUPTIONS` that
    `interrupt` handles is taken by the loop while ``main`` runs: it cancels ``main``, whose
    clean-up runs as the cancellation unwinds, and the `KeyboardInterrupt` naming the signal
    is raised once the loop is closed.
    """
    import asyncio

    caught: list[str] = []
    try:
        result = asyncio.run(_cancelled_by_interruptions(main, caught))
    except asyncio.CancelledError:
        if not caught:
            raise
    if caught:
        raise KeyboardInterrupt(caught[0])
    return result


async def _cancelled_by_interruptions(main: Coroutine[Any, Any, T], caught: list[str]) -> T:
    """Await ``main``, each interruption cancelling it and adding its name to ``caught``."""
    import asyncio

    loop = asyncio.get_running_loop()
    task = asyncio.current_task()
    assert task is not None
    in_main_thread = threading.current_thread() is threading.main_thread()
    handled = [s for s in INTERRUPTIONS if in_main_thread and signal.getsignal(s) is interrupt]

    def cancel(signum: int) -> None:
        caught.append(signal.Signals(signum).name)
        task.cancel()

    for signum in handled:
        loop.add_signal_handler(signum, cancel, signum)
    try:
        return await main
    finally:
        for signum in handled:
            loop.remove_signal_handler(signum)
            signal.signal(signum, interrupt)
