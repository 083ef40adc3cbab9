"""Progress bars on long commands, through the console script: shown with the time left under a
terminal (a pseudo-terminal, as a user's shell gives), and as plain lines when standard error is
a file or a pipe."""

from __future__ import annotations

import os
import pty
import re
import select
import subprocess
import sys
from pathlib import Path

import pytest

CONSOLE = "from mirror_avatar.console import run; run()"

TIME_LEFT = re.compile(r"\[\d\d:\d\d<\d\d:\d\d")
"""tqdm's elapsed<remaining field."""

COMMANDS = {
    "train": (["train", "--target", "bundled:fast", "--partners", "bundled:slow", "--sessions",
               "12", "--duration", "10", "--jobs", "1", "--out", "{out}/p.npz"],
              "training:", "12/12"),
    "train dqn": (["train", "--target", "bundled:fast", "--partners", "bundled:slow", "--agent",
                   "dqn", "--sessions", "6", "--duration", "10", "--jobs", "1",
                   "--out", "{out}/d.npz"], "training:", "6/6"),
    "group train": (["group", "train", "--target", "bundled:slow", "--player", "bundled:fast",
                     "--player", "bundled:slow", "--sessions", "3", "--duration", "5", "--jobs",
                     "1", "--out", "{out}/g.npz"], "training:", "3/3"),
    "signature": (["signature", "--bundled", "--out", "{out}/s"], "signatures:", "18/18"),
    "curriculum": (["curriculum", "--patient", "bundled:slow", "--target", "bundled:fast",
                    "--stages", "2", "--out", "{out}/c"], "curriculum stages:", "4/4"),
}  # fmt: skip
"""Command, the bar's label, and its last count."""


def on_a_terminal(arguments: list[str]) -> tuple[int, str]:
    """Run the console script on a new pseudo-terminal (which reports no width, like some
    terminals do) and return its exit code and everything it wrote."""
    pid, fd = pty.fork()
    if pid == 0:  # the child
        os.execv(sys.executable, [sys.executable, "-c", CONSOLE, *arguments])
    output = bytearray()
    while True:
        ready, _, _ = select.select([fd], [], [], 600)
        if not ready:
            os.kill(pid, 9)
            break
        try:
            data = os.read(fd, 65536)
        except OSError:  # the child closed the terminal
            break
        if not data:
            break
        output += data
    _, status = os.waitpid(pid, 0)
    os.close(fd)
    return os.waitstatus_to_exitcode(status), output.decode(errors="replace")


@pytest.mark.long
@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_long_command_shows_progress_on_a_terminal(name: str, tmp_path: Path) -> None:
    arguments, label, last = COMMANDS[name]
    status, output = on_a_terminal([a.format(out=tmp_path) for a in arguments])
    assert status == 0, output
    bars = [line for line in output.split("\r") if line.strip().startswith(label)]
    assert bars, output
    assert last in bars[-1] and "100%" in bars[-1]
    assert any(TIME_LEFT.search(bar) for bar in bars)


@pytest.mark.long
@pytest.mark.parametrize("name", list(COMMANDS))
def test_off_a_terminal_plain_lines_say_the_progress(name: str, tmp_path: Path) -> None:
    """Standard error to a file: a plain line at each tenth of the work, no bar drawn in place."""
    arguments, label, last = COMMANDS[name]
    log = tmp_path / "stderr.log"
    with log.open("w") as stderr:
        result = subprocess.run(
            [sys.executable, "-c", CONSOLE, *(a.format(out=tmp_path) for a in arguments)],
            stdout=subprocess.PIPE, stderr=stderr, text=True, check=False,
        )  # fmt: skip
    errors = log.read_text()
    assert result.returncode == 0, errors
    lines = [line for line in errors.splitlines() if line.startswith(label)]
    assert lines, errors
    assert lines[-1].startswith(f"{label} {last} ") and "(100 %)" in lines[-1], lines
    assert "left" in lines[0] and "%|" not in errors + result.stdout
    assert b"\r" not in log.read_bytes()  # read as text, a carriage return would end a line
