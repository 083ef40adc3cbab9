"""Run the console entry point in a child forked from the test process.

The tests of what a command refuses (a FIFO given as a file, a folder where an output goes, a
bad number) need a child process: a regression that opens a FIFO must hang the child, not the
test run, and the exit code and standard error must be the command line's own. A fresh
interpreter spends seconds importing NumPy, SciPy, scikit-learn and matplotlib before the
command reads its first argument; a child forked from the test process starts with them
imported and runs `mirror_avatar.console.run` at once, with the arguments, working folder and
environment variables given.

The child is made to behave as a fresh process would: standard output and error go to files,
warnings are printed with Python's default filters (the test run turns them into errors), and
uncaught exceptions in threads reach standard error. A fresh interpreter's start is tested
where it matters (the first command, progress bars, signals), with `subprocess`.

It is for commands refused before their work: a forked child must not start the thread pools
the test process may hold (GNU OpenMP, behind scikit-learn's k-means, is not safe after a
fork), so a command that trains or fits runs with `subprocess`.
"""

from __future__ import annotations

import io
import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
import traceback
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO

PROGRAM = "mirror-avatar"
"""The name the child's ``sys.argv[0]`` is given, as the console script has."""


def run_console(
    arguments: Sequence[str],
    cwd: Path,
    *,
    timeout: float,
    env: Mapping[str, str] | None = None,
) -> subprocess.CompletedProcess[str]:
    """Run ``mirror-avatar ARGUMENTS`` in a forked child, in ``cwd``; wait at most ``timeout`` s.

    ``env`` holds variables set in the child on top of this process's environment.

    Returns what `subprocess.run` with ``capture_output=True, text=True`` returns (stdout and
    stderr decoded as UTF-8); raises `subprocess.TimeoutExpired` after killing a child that
    still runs at the deadline.
    """
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the child
            _run_in_child(list(arguments), cwd, env, out.fileno(), err.fileno())
        returncode = _wait(pid, timeout, arguments)
        return subprocess.CompletedProcess(
            [PROGRAM, *arguments], returncode, _read(out), _read(err)
        )


def _run_in_child(
    arguments: list[str], cwd: Path, env: Mapping[str, str] | None, out: int, err: int
) -> None:  # pragma: no cover - runs in the child
    """Become a fresh command-line process and run the console entry point; never returns."""
    code = 1
    try:
        os.dup2(out, 1)
        os.dup2(err, 2)
        null = os.open(os.devnull, os.O_RDONLY)
        os.dup2(null, 0)
        sys.stdin = io.TextIOWrapper(io.FileIO(0, "r", closefd=False), encoding="utf-8")
        sys.stdout = io.TextIOWrapper(io.FileIO(1, "w", closefd=False), encoding="utf-8")
        sys.stderr = io.TextIOWrapper(
            io.FileIO(2, "w", closefd=False),
            encoding="utf-8",
            errors="backslashreplace",
            line_buffering=True,
        )
        _default_error_reporting()
        os.chdir(cwd)
        os.environ.update(env or {})
        sys.argv = [PROGRAM, *arguments]
        from mirror_avatar.console import run

        run()
        code = 0
    except SystemExit as exit:
        code = _exit_code(exit)
    except BaseException:
        traceback.print_exc()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:
                code = code or 1
        os._exit(code)


def _default_error_reporting() -> None:  # pragma: no cover - runs in the child
    """Python's default warning filters and exception hooks, as a fresh interpreter has them."""
    warnings.resetwarnings()
    warnings.simplefilter("ignore", ResourceWarning)
    warnings.simplefilter("ignore", ImportWarning)
    warnings.simplefilter("ignore", PendingDeprecationWarning)
    warnings.simplefilter("ignore", DeprecationWarning)
    warnings.filterwarnings("default", category=DeprecationWarning, module="__main__")
    warnings.showwarning = _print_warning
    sys.excepthook = sys.__excepthook__
    sys.unraisablehook = sys.__unraisablehook__
    threading.excepthook = threading.__excepthook__
    signal.signal(signal.SIGALRM, signal.SIG_DFL)


def _print_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: io.TextIOBase | None = None,
    line: str | None = None,
) -> None:  # pragma: no cover - runs in the child
    """Print a warning to standard error as Python does."""
    sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


def _exit_code(exit: SystemExit) -> int:  # pragma: no cover - runs in the child
    """The exit status `sys.exit` gives for ``exit``'s code, printing a message as it does."""
    if exit.code is None or isinstance(exit.code, int):
        return exit.code or 0
    print(exit.code, file=sys.stderr)
    return 1


def _wait(pid: int, timeout: float, arguments: Sequence[str]) -> int:
    """The child's return code as `subprocess` gives it (negative: killed by that signal)."""
    descriptor = os.pidfd_open(pid)
    try:
        ready, _, _ = select.select([descriptor], [], [], timeout)
        if not ready:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            raise subprocess.TimeoutExpired([PROGRAM, *arguments], timeout)
    finally:
        os.close(descriptor)
    status = os.waitpid(pid, 0)[1]
    return os.waitstatus_to_exitcode(status)


def _read(file: IO[bytes]) -> str:
    """Everything written to ``file``, as text."""
    file.seek(0)
    return file.read().decode("utf-8", errors="replace")
