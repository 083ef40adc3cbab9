"""Files that are not regular files, and paths no file can have, through the real command line.

A named pipe (FIFO) given where a file is read blocks its reader for ever if it is opened; a
device never ends; a socket or a folder cannot be read as a file. Each is given, in a child
process running the real console entry point, as every kind of input a command reads (a model
``.npz`` spec, a ``vt:`` recording, trial files of each format, a session, a graph), and must be
refused at once: one line naming the file and what it is, exit code 2. The child's timeout is
only a safety net so that a regression fails instead of hanging the test run.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from mirror_avatar.errors import InputError
from mirror_avatar.specs import load_player
from mirror_avatar.user_files import MAX_PART_BYTES

SAFETY_TIMEOUT = 300
"""Seconds after which a child that still runs is killed (a hang, not a slow machine)."""

Arguments = Callable[[Path], list[str]]
"""Command-line arguments reading the file given."""

READERS: dict[str, tuple[str, Arguments]] = {
    "model spec": ("player.npz", lambda f: ["simulate", "--leader", str(f), "--follower",
                                            "bundled:slow", "--duration", "5"]),
    "vt spec": ("recording.csv", lambda f: ["simulate", "--leader", f"vt:{f}", "--follower",
                                            "bundled:slow", "--duration", "5"]),
    "generator sample": ("model.npz", lambda f: ["generator", "sample", str(f)]),
    "csv trial": ("trial.csv", lambda f: ["signature", str(f)]),
    "mat trials": ("trials.mat", lambda f: ["generator", "fit", str(f), "--out", "out.npz"]),
    "parquet trial": ("trial.parquet", lambda f: ["signature", str(f)]),
    "bids trial": ("sub-1_task-mirror_motion.tsv", lambda f: ["signature", str(f)]),
    "session": ("session.csv", lambda f: ["evaluate", str(f)]),
    "graph": ("graph.json", lambda f: ["group", "simulate", "--player", "bundled:fast",
                                       "--player", "bundled:slow", "--graph", str(f),
                                       "--duration", "5"]),
}  # fmt: skip
"""Each kind of input: the file name it is given as, and a command reading it (writing in
``out``, or ``out.npz``, in the working folder)."""


def bound_socket(path: Path) -> None:
    """Leave a Unix socket file at ``path``."""
    with socket.socket(socket.AF_UNIX) as listener:
        listener.bind(str(path))


def with_out(arguments: list[str]) -> list[str]:
    """The arguments with ``--out out`` added unless they name their output."""
    return arguments if "--out" in arguments else [*arguments, "--out", "out"]


def run_cli(arguments: list[str], folder: Path) -> subprocess.CompletedProcess[str]:
    """Run the console entry point in a child process, in ``folder``."""
    command = "from mirror_avatar.cli import run; run()"
    return subprocess.run(
        [sys.executable, "-c", command, *arguments],
        capture_output=True,
        text=True,
        check=False,
        cwd=folder,
        timeout=SAFETY_TIMEOUT,
    )


def one_line(result: subprocess.CompletedProcess[str], *words: str) -> str:
    """Check the child refused its input in one line with exit code 2, saying ``words``."""
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mirror-avatar: error: "), result.stderr
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize("reader", sorted(READERS))
def test_a_fifo_is_refused_unopened(tmp_path: Path, reader: str) -> None:
    name, arguments = READERS[reader]
    fifo = tmp_path / name
    os.mkfifo(fifo)
    if name.endswith("_motion.tsv"):
        (tmp_path / name.replace(".tsv", ".json")).write_text('{"SamplingFrequency": 100}')
    result = run_cli(with_out(arguments(fifo)), tmp_path)
    one_line(result, name, "is a named pipe (FIFO), not a regular file")
    assert not list(tmp_path.glob("out*"))


NOT_REGULAR: dict[str, tuple[Callable[[Path], None], str]] = {
    "device": (lambda path: path.symlink_to("/dev/zero"), "is a character device"),
    "folder": (lambda path: path.mkdir(), "is a folder"),
    "socket": (bound_socket, "is a socket"),
}
"""Files that are not regular: how to make one, and what the error line calls it."""


@pytest.mark.parametrize(
    ("reader", "other"),
    [("model spec", "device"), ("model spec", "folder"), ("model spec", "socket"),
     ("generator sample", "folder"), ("csv trial", "device"), ("csv trial", "socket"),
     ("session", "device")],
)  # fmt: skip
def test_other_files_that_are_not_regular_are_refused(
    tmp_path: Path, reader: str, other: str
) -> None:
    # A folder given as a trial or a session is read as a folder of them, so not here.
    make, kind = NOT_REGULAR[other]
    name, arguments = READERS[reader]
    make(tmp_path / name)
    result = run_cli(with_out(arguments(tmp_path / name)), tmp_path)
    one_line(result, name, kind)


def test_a_path_part_longer_than_a_file_name_can_be_is_one_line(tmp_path: Path) -> None:
    long = "a" * (MAX_PART_BYTES + 1) + ".csv"
    _, arguments = READERS["vt spec"]
    result = run_cli(with_out(arguments(tmp_path / long)), tmp_path)
    one_line(result, f"a part of the path is {len(long)} bytes, over the {MAX_PART_BYTES}")


@pytest.mark.parametrize("spec", ["vt:trial\0.csv", "player\0.npz", "trial\0.csv"])
def test_a_nul_byte_in_a_spec_is_one_line(spec: str) -> None:
    # A command line cannot carry a NUL byte; a lab plan or a caller of the API can.
    with pytest.raises(InputError, match="the path holds a NUL byte") as caught:
        load_player(spec, "leader")
    assert "\0" not in str(caught.value) and "\n" not in str(caught.value)
