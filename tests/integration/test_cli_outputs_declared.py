"""Every file a command writes is checked before its work, not only its ``--out``.

A command writes more than the path it is given: a training run its learning curve and
checkpoint beside the policy, ``avatar create`` the avatar's card, folder commands their
reports, figures and sidecars. For each command a folder is put where one of these files goes;
the real console entry point, in a child process, must refuse at once in one line naming that
path, exit code 2, and write nothing (the folder in the way is all there is).
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from console_child import run_console
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.trial_io import write_csv_trial

SAFETY_TIMEOUT = 600
"""Seconds after which a child that still runs is killed (the refusal comes at once)."""

Case = tuple[Callable[[Path], list[str]], str]
"""Arguments given the folder of inputs and the output (``out`` or ``out.npz``), and the output
file (relative to the working folder) that a folder is put in the way of."""

TRAINING = ["--sessions", "4", "--duration", "5", "--jobs", "1", "--out", "out.npz"]

CASES: dict[str, Case] = {
    "train curve": (lambda i: ["train", "--target", "bundled:slow", "--partners", "bundled:fast",
                               *TRAINING], "out.learning_curve.csv"),
    "train figure": (lambda i: ["train", "--target", "bundled:slow", "--partners", "bundled:fast",
                                *TRAINING], "out.learning_curve.png"),
    "group train checkpoint": (lambda i: ["group", "train", "--target", "bundled:slow",
                                          "--player", "bundled:fast", "--player", "bundled:fast",
                                          *TRAINING], "out.checkpoint.npz"),
    "avatar create card": (lambda i: ["avatar", "create", str(i / "trials"), "--name", "P",
                                      "--sessions", "2", "--jobs", "1", "--out", "out.npz"],
                           "out.html"),
    "curriculum stage": (lambda i: ["curriculum", "--patient", "bundled:slow", "--target",
                                    "bundled:fast", "--stages", "3", "--out", "out"],
                         "out/stage-3.npz"),
    "curriculum report": (lambda i: ["curriculum", "--patient", "bundled:slow", "--target",
                                     "bundled:fast", "--out", "out"], "out/report.html"),
    "generator fit sweep": (lambda i: ["generator", "fit", str(i / "trials"), "--kind", "ims",
                                       "--sweep", "--out", "out.npz"], "out.sweep.csv"),
    "generator sample manifest": (lambda i: ["generator", "sample", str(i / "model.npz"),
                                             "--count", "3", "--out", "out"],
                                  "out/samples.json"),
    "generator sample trial": (lambda i: ["generator", "sample", str(i / "model.npz"),
                                          "--count", "3", "--out", "out"],
                               "out/generated-003.csv"),
    "simulate metrics": (lambda i: ["simulate", "--leader", "bundled:fast", "--follower",
                                    "bundled:slow", "--duration", "5", "--out", "out"],
                         "out/metrics.json"),
    "simulate figure": (lambda i: ["simulate", "--leader", "bundled:fast", "--follower",
                                   "bundled:slow", "--duration", "5", "--out", "out"],
                        "out/relative_phase.png"),
    "group simulate sidecar": (lambda i: ["group", "simulate", "--player", "bundled:fast",
                                          "--player", "bundled:slow", "--player", "bundled:fast",
                                          "--duration", "5", "--out", "out"], "out/session.json"),
    "signature figure": (lambda i: ["signature", str(i / "trials"), "--out", "out"],
                         "out/strokes.png"),
    "signature report": (lambda i: ["signature", str(i / "trials"), "--out", "out"],
                         "out/report.html"),
    "reproduce report": (lambda i: ["reproduce", "--quick", "--out", "out"], "out/report.html"),
    "convert trial": (lambda i: ["convert", str(i / "trials"), "--out", "out"],
                      "out/trials/trial1.csv"),
    "convert manifest": (lambda i: ["convert", str(i / "trials"), "--out", "out"],
                         "out/convert.json"),
    "evaluate table": (lambda i: ["evaluate", str(i / "trials"), "--out", "out"],
                       "out/sessions.csv"),
    "lab export participants": (lambda i: ["lab", "export", str(i), "--out", "out"],
                                "out/participants.tsv"),
}  # fmt: skip


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder of three trials (``trials/trial0.csv``...) and a generator model."""
    folder = tmp_path_factory.mktemp("inputs")
    (folder / "trials").mkdir()
    for k, trial in enumerate(load_zhai2017()[:3]):
        write_csv_trial(trial, folder / "trials" / f"trial{k}.csv")
    command = "from mirror_avatar.console import run; run()"
    arguments = ["generator", "fit", str(folder / "trials"), "--kind", "ims", "--symbols", "16"]
    subprocess.run(
        [sys.executable, "-c", command, *arguments, "--out", str(folder / "model.npz")],
        check=True,
        capture_output=True,
        timeout=SAFETY_TIMEOUT,
    )
    return folder


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_folder_in_the_way_of_any_output_is_refused_before_work(
    inputs: Path, tmp_path: Path, case: str
) -> None:
    arguments, blocked = CASES[case]
    (tmp_path / blocked / "kept.txt").parent.mkdir(parents=True)
    (tmp_path / blocked / "kept.txt").write_text("mine")
    before = sorted(tmp_path.rglob("*"))
    cache = {"XDG_CACHE_HOME": str(tmp_path.parent / "cache")}
    result = run_console(arguments(inputs), tmp_path, timeout=SAFETY_TIMEOUT, env=cache)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mirror-avatar: error: "), result.stderr
    assert f"{blocked}: is a folder where this command writes a file" in lines[0]
    assert sorted(tmp_path.rglob("*")) == before
    assert (tmp_path / blocked / "kept.txt").read_text() == "mine"
