"""Signals through the console script, with real processes: a signal ignored at the start
(``nohup``) stays ignored, one that arrives stops the command with exit code 130 and is named,
also while the program is still starting."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from mirror_avatar.common.interruptions import INTERRUPTIONS
from waiting import wait_for

CONSOLE = "from mirror_avatar.console import run; run()"

LONG_RUN = ["train", "--target", "bundled:fast", "--partners", "bundled:slow", "--sessions", "1000",
            "--duration", "20",
            "--jobs", "1"]  # fmt: skip
"""A command that works for minutes."""


@contextlib.contextmanager
def started(command: list[str], ignore: tuple[int, ...] = ()) -> Iterator[subprocess.Popen[str]]:
    """Start ``command`` in its own session, with ``ignore`` signals ignored (as nohup does).

    The others of `INTERRUPTIONS` get their default action back: the test run itself may have
    been started with some ignored (under ``nohup``, or in the background by a shell, which
    ignores SIGINT), and a child inherits what its parent ignores.
    """

    def ignoring() -> None:
        for signum in INTERRUPTIONS:
            signal.signal(signum, signal.SIG_IGN if signum in ignore else signal.SIG_DFL)

    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True, preexec_fn=ignoring)  # fmt: skip
    try:
        yield process
    finally:
        if process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGKILL)
        process.communicate()


def wait_for_start(process: subprocess.Popen[str], marker: Path) -> None:
    """Wait until the command is running (it has written ``marker``), at most ten minutes."""
    wait_for(lambda: marker.exists() or process.poll() is not None, 600.0, f"{marker.name}")
    assert process.poll() is None and marker.exists(), "the command did not start"


def caught_signals(pid: int) -> int:
    """The mask of signals process ``pid`` has handlers for (Linux ``/proc``)."""
    status = Path(f"/proc/{pid}/status").read_text()
    return int(
        next(line for line in status.splitlines() if line.startswith("SigCgt:")).split()[1], 16
    )


def test_a_signal_at_the_first_instant_is_an_abort(tmp_path: Path) -> None:
    """SIGTERM sent as soon as the handler is in place, before numba (LLVM) is even loaded:
    the command line is still being imported, and the program ends as an abort (exit 130)."""
    command = [sys.executable, "-c", CONSOLE, "info"]
    with started(command) as process:
        sigterm = 1 << (signal.SIGTERM - 1)
        wait_for(lambda: caught_signals(process.pid) & sigterm, 120.0, interval=0.001)
        maps = Path(f"/proc/{process.pid}/maps").read_text()
        process.send_signal(signal.SIGTERM)
        out, error = process.communicate(timeout=120)
    assert "llvmlite" not in maps, "the handler came after the heavy imports"
    assert process.returncode == 130, error
    assert out == "" and error.strip().splitlines()[-1] == "mirror-avatar: aborted (SIGTERM)"
    assert "Traceback" not in error


@pytest.mark.long
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_the_signal_that_stopped_a_command_is_named(signum: int, tmp_path: Path) -> None:
    out = tmp_path / "p.npz"
    command = [sys.executable, "-c", CONSOLE, *LONG_RUN, "--checkpoint-every", "1",
               "--out", str(out)]  # fmt: skip
    with started(command) as process:
        wait_for_start(process, tmp_path / "p.checkpoint.npz")
        process.send_signal(signum)
        _, error = process.communicate(timeout=120)
    assert process.returncode == 130, error
    name = signal.Signals(signum).name
    assert error.strip().splitlines()[-1] == f"mirror-avatar: aborted ({name})"
    assert "Traceback" not in error


@pytest.mark.long
def test_nohup_keeps_a_command_running_past_a_hangup(tmp_path: Path) -> None:
    """SIGHUP ignored at the start (nohup) is still ignored; SIGTERM still stops the command."""
    out = tmp_path / "p.npz"
    command = [sys.executable, "-c", CONSOLE, *LONG_RUN, "--checkpoint-every", "1",
               "--out", str(out)]  # fmt: skip
    with started(command, ignore=(signal.SIGHUP,)) as process:
        checkpoint = tmp_path / "p.checkpoint.npz"
        wait_for_start(process, checkpoint)
        process.send_signal(signal.SIGHUP)
        first = checkpoint.stat().st_mtime_ns
        rewritten = lambda: checkpoint.stat().st_mtime_ns != first  # noqa: E731
        wait_for(lambda: rewritten() or process.poll() is not None, 600.0)  # still working
        assert process.poll() is None, process.communicate()[1]
        process.send_signal(signal.SIGTERM)
        _, error = process.communicate(timeout=120)
    assert process.returncode == 130, error
    assert error.strip().splitlines()[-1] == "mirror-avatar: aborted (SIGTERM)"
