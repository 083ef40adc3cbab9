"""Output paths are checked before any work: one line, exit code 2, nothing written or lost.

Each command is given an ``--out`` it cannot write - inside a file, inside a folder that cannot
be written (``/proc``, unwritable even for root), or of the wrong kind (a folder where a file
goes, a file where a folder goes) - and must refuse it at once, leaving what is there as it was.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from mirror_avatar.cli import main
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.trial_io import write_csv_trial
from mirror_avatar.motion.generator import IMSGenerator

Arguments = Callable[[Path, Path], list[str]]
"""Command-line arguments given the folder of inputs and the ``--out`` to try."""

FOLDER_OUTPUTS: dict[str, Arguments] = {
    "simulate": lambda inputs, out: ["simulate", "--leader", "bundled:fast", "--follower",
                                     "bundled:slow", "--duration", "5", "--out", str(out)],
    "group simulate": lambda inputs, out: ["group", "simulate", "--player", "bundled:fast",
                                           "--player", "bundled:slow", "--player", "bundled:fast",
                                           "--duration", "5", "--out", str(out)],
    "generator sample": lambda inputs, out: ["generator", "sample", str(inputs / "model.npz"),
                                             "--out", str(out)],
    "convert": lambda inputs, out: ["convert", str(inputs / "trial.csv"), "--out", str(out)],
    "evaluate": lambda inputs, out: ["evaluate", str(inputs / "session"), "--out", str(out)],
    "reproduce": lambda inputs, out: ["reproduce", "--quick", "--out", str(out)],
    "signature": lambda inputs, out: ["signature", str(inputs / "trial.csv"),
                                      str(inputs / "trial2.csv"), "--out", str(out)],
    "play": lambda inputs, out: ["play", "--port", "0", "--out", str(out)],
    "lab": lambda inputs, out: ["lab", "--port", "0", "--out", str(out)],
    "lab export": lambda inputs, out: ["lab", "export", str(inputs / "session"), "--out",
                                       str(out)],
}  # fmt: skip
FILE_OUTPUTS: dict[str, Arguments] = {
    "train": lambda inputs, out: ["train", "--target", "bundled:slow", "--partners",
                                  "bundled:fast", "--sessions", "4", "--duration", "5",
                                  "--jobs", "1", "--out", str(out)],
    "group train": lambda inputs, out: ["group", "train", "--target", "bundled:slow", "--player",
                                        "bundled:fast", "--player", "bundled:fast",
                                        "--sessions", "4", "--duration", "5", "--jobs", "1",
                                        "--out", str(out)],
    "generator fit": lambda inputs, out: ["generator", "fit", str(inputs / "trial.csv"),
                                          str(inputs / "trial2.csv"), "--out", str(out)],
}  # fmt: skip
UNWRITABLE = Path("/proc/mirror-avatar-test")


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two trial files, a generator model and a session folder."""
    folder = tmp_path_factory.mktemp("inputs")
    trials = load_zhai2017()
    write_csv_trial(trials[0], folder / "trial.csv")
    write_csv_trial(trials[1], folder / "trial2.csv")
    assert main(["generator", "fit", str(folder / "trial.csv"), str(folder / "trial2.csv"),
                 "--kind", "ims", "--symbols", "16",
                 "--out", str(folder / "model.npz")]) == 0  # fmt: skip
    assert main(FOLDER_OUTPUTS["simulate"](folder, folder / "session")[:-2]
                + ["--seed", "1", "--out", str(folder / "session")]) == 0  # fmt: skip
    return folder


def refused(capsys: pytest.CaptureFixture[str], arguments: list[str], *words: str) -> str:
    """Run the command line; check it refused in one line that says ``words``."""
    capsys.readouterr()
    status = main(arguments)
    error = capsys.readouterr().err
    assert status == 2, error
    assert error.count("\n") == 1 and error.startswith("mirror-avatar: error: "), error
    for word in words:
        assert word in error, error
    return error


def snapshot(folder: Path) -> dict[Path, bytes]:
    return {path: path.read_bytes() for path in folder.rglob("*") if path.is_file()}


@pytest.mark.parametrize("command", sorted(FOLDER_OUTPUTS | FILE_OUTPUTS))
def test_an_output_inside_a_file_is_refused_first(tmp_path, capsys, inputs, command) -> None:
    blocker = tmp_path / "notes.txt"
    blocker.write_text("kept\n")
    name = "out.npz" if command in FILE_OUTPUTS else "out"
    arguments = (FOLDER_OUTPUTS | FILE_OUTPUTS)[command](inputs, blocker / "sub" / name)
    refused(capsys, arguments, str(blocker), "--out")
    assert blocker.read_text() == "kept\n"


@pytest.mark.parametrize("command", sorted(FOLDER_OUTPUTS | FILE_OUTPUTS))
def test_an_output_in_an_unwritable_folder_is_refused_first(capsys, inputs, command) -> None:
    name = "out.npz" if command in FILE_OUTPUTS else "out"
    arguments = (FOLDER_OUTPUTS | FILE_OUTPUTS)[command](inputs, UNWRITABLE / name)
    refused(capsys, arguments, "cannot write in /proc", "--out")


@pytest.mark.parametrize("command", sorted(FOLDER_OUTPUTS))
def test_a_file_where_a_folder_goes_is_refused(tmp_path, capsys, inputs, command) -> None:
    existing = tmp_path / "results"
    existing.write_text("earlier results\n")
    refused(capsys, FOLDER_OUTPUTS[command](inputs, existing), str(existing), "not a folder")
    assert existing.read_text() == "earlier results\n"


@pytest.mark.parametrize("command", sorted(FILE_OUTPUTS))
def test_a_folder_where_a_file_goes_is_refused(tmp_path, capsys, inputs, command) -> None:
    existing = tmp_path / "policy.npz"
    existing.mkdir()
    (existing / "kept.txt").write_text("kept\n")
    before = snapshot(tmp_path)
    refused(capsys, FILE_OUTPUTS[command](inputs, existing), str(existing), "is a folder")
    assert snapshot(tmp_path) == before


def test_an_internal_error_is_one_line_with_exit_1(capsys, monkeypatch, inputs) -> None:
    """A bug, not bad input: one line naming the error, and how to see the traceback."""

    def broken(*args: object, **kwargs: object) -> None:
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(IMSGenerator, "fit", broken)
    monkeypatch.delenv("MIRROR_AVATAR_DEBUG", raising=False)
    status = main(["generator", "fit", str(inputs / "trial.csv"), str(inputs / "trial2.csv"),
                   "--kind", "ims", "--symbols", "16",
                   "--out", str(inputs / "broken.npz")])  # fmt: skip
    error = capsys.readouterr().err
    assert status == 1 and error.count("\n") == 1, error
    assert "ZeroDivisionError" in error and "MIRROR_AVATAR_DEBUG=1" in error
    assert not (inputs / "broken.npz").exists()
