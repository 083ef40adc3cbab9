"""Files that are not regular files, and paths no file can have, through the real command line.

A named pipe (FIFO) given where a file is read blocks its reader for ever if it is opened; a
device never ends; a socket or a folder cannot be read as a file. Each is given, in a child
process running the real console entry point, as every kind of input a command reads (a model
``.npz`` spec, a ``vt:`` recording, trial files of each format, a session, a graph), and must be
refused at once: one line naming the file and what it is, exit code 2. The child's timeout is
only a safety net so that a regression fails instead of hanging the test run.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from console_child import run_console
from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.bids.writing import write_bids_motion
from mirror_avatar.files.user_files import MAX_PART_BYTES
from mirror_avatar.sessions.graphs import complete_graph
from mirror_avatar.sessions.writer import SessionWriter
from mirror_avatar.specs import load_player

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
    return run_console(arguments, folder, timeout=SAFETY_TIMEOUT)


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
    result = run_cli(["simulate", "--leader", "bundled:fast", "--follower", "bundled:slow",
                      "--duration", "5", "--out", long], tmp_path)  # fmt: skip
    one_line(result, f"a part of the path is {len(long)} bytes, over the {MAX_PART_BYTES}")


@pytest.mark.parametrize("spec", ["vt:trial\0.csv", "player\0.npz", "trial\0.csv"])
def test_a_nul_byte_in_a_spec_is_one_line(spec: str) -> None:
    # A command line cannot carry a NUL byte; a lab plan or a caller of the API can.
    with pytest.raises(InputError, match="the path holds a NUL byte") as caught:
        load_player(spec, "leader")
    assert "\0" not in str(caught.value) and "\n" not in str(caught.value)


DEEP = "[" * 100_000 + "]" * 100_000
"""JSON nested far deeper than Python's recursion limit allows a reader to go."""


def lab_session(folder: Path) -> Path:
    """A lab session folder of one recorded dyad trial, written as the lab writes it."""
    session = folder / "2025-03-01_dyad"
    session.mkdir()
    (session / "plan.json").write_text('{"session_id": "2025-03-01_dyad"}')
    slots = [{"label": "P1", "kind": "human", "role": "leader", "spec": None, "device": "pointer"},
             {"label": "av", "kind": "avatar", "role": "follower", "spec": "bundled:fast",
              "device": None}]  # fmt: skip
    lab = {"session_id": "2025-03-01_dyad", "trial": 1, "condition": "dyad", "slots": slots}
    writer = SessionWriter(session / "trial-01_session.csv", ["P1", "av"], ["leader", "follower"],
                           complete_graph(2), 0.03, {"lab": lab})  # fmt: skip
    t = np.arange(200) * 0.03
    for row in np.column_stack(
        [t, *(f(t + k) for k in (0, 1) for f in (np.sin, np.cos, np.sin, np.cos))]
    ):
        writer.append(row)
    writer.close(True, {"dropped": {}, "held": {"P1": 0}})
    return session


def test_deep_json_beside_a_session_is_one_line(tmp_path: Path) -> None:
    session = lab_session(tmp_path)
    (session / "trial-01_session.json").write_text(DEEP)
    for arguments in (["evaluate", str(session / "trial-01_session.csv")],
                      ["lab", "export", str(session), "--out", "bids"]):  # fmt: skip
        result = run_cli(arguments, tmp_path)
        one_line(result, "trial-01_session.json", "nested deeper than the limit of 32 levels")
    assert not (tmp_path / "bids").exists()


def test_deep_json_in_a_motion_sidecar_is_one_line(tmp_path: Path) -> None:
    motion = tmp_path / "sub-1_task-mirror_motion.tsv"
    write_bids_motion(load_zhai2017()[0].resampled(100.0), motion)
    motion.with_name("sub-1_task-mirror_motion.json").write_text('{"a": ' + DEEP + "}")
    for command in ("evaluate", "signature"):
        result = run_cli([command, str(motion), "--out", "out"], tmp_path)
        one_line(result, "_motion.json", "nested deeper than the limit of 32 levels")


@pytest.mark.parametrize(
    ("key", "value", "problem"),
    [("start_time", 1e300, "give samples no distinct times"),
     ("start_time", "Infinity", "Infinity is not a JSON number"),
     ("SamplingFrequency", "1" + "0" * 400, "is beyond the range of float64")],
)  # fmt: skip
def test_absurd_numbers_in_an_exported_trial_are_one_line(
    tmp_path: Path, key: str, value: object, problem: str
) -> None:
    session = lab_session(tmp_path)
    assert run_cli(["lab", "export", str(session), "--out", "bids"], tmp_path).returncode == 0
    motion = next((tmp_path / "bids").rglob("*_motion.tsv"))
    sidecar = motion.with_name(motion.name.replace(".tsv", ".json"))
    info = json.loads(sidecar.read_text())
    placeholder = "@@value@@"
    if key == "start_time":
        info["MirrorGame"][key] = placeholder
    else:
        info[key] = placeholder
    sidecar.write_text(json.dumps(info).replace(f'"{placeholder}"', str(value)))
    one_line(run_cli(["evaluate", str(motion)], tmp_path), sidecar.name, problem)
