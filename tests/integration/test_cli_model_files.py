"""Model files through the real command line: what they say is checked, and they are reproducible.

A stage whose two generators move at different rates is refused naming the stage's file; a cyber
player claiming a role no trainer gives is refused instead of skipping the role check; and two
identical ``avatar create`` runs write the same bytes (no build timings, no archive dates).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from console_child import run_console
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.model_files import read_archive, save_model
from mirror_avatar.files.trial_io import write_csv_trial
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.signatures.signature import DEFAULT_BINS
from mirror_avatar.specs import POLICY_ROLES, bundled_generator
from mirror_avatar.training.curriculum import FORMAT_NAME, FORMAT_VERSION, StageMotion, save_stage

SAFETY_TIMEOUT = 900
"""Seconds after which a child that still runs is killed."""


def run_cli(arguments: list[str], folder: Path) -> subprocess.CompletedProcess[str]:
    """Run the console entry point in a child process in ``folder`` (its own model cache)."""
    return subprocess.run(
        [sys.executable, "-c", "from mirror_avatar.console import run; run()", *arguments],
        capture_output=True,
        text=True,
        check=False,
        cwd=folder,
        env=dict(os.environ) | {"XDG_CACHE_HOME": str(folder / "cache")},
        timeout=SAFETY_TIMEOUT,
    )


def run_refused(arguments: list[str], folder: Path) -> subprocess.CompletedProcess[str]:
    """Run a command refused before its work in a child forked from this process, in ``folder``
    (its own model cache)."""
    cache = {"XDG_CACHE_HOME": str(folder / "cache")}
    return run_console(arguments, folder, timeout=SAFETY_TIMEOUT, env=cache)


def one_line(result: subprocess.CompletedProcess[str]) -> str:
    """The one error line of a refused command (exit code 2)."""
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mirror-avatar: error: "), result.stderr
    return lines[0]


def test_a_stage_of_two_rates_is_refused_naming_its_file(tmp_path: Path) -> None:
    generator = bundled_generator("slow")
    path = save_stage(StageMotion(generator, generator, 0.5, "mixture"), tmp_path / "s.npz", {})
    arrays, metadata = read_archive(path)
    metadata["target"]["parameters"]["rate"] = 50.0
    del metadata["format"], metadata["version"], metadata["library_version"]
    save_model(path, FORMAT_NAME, FORMAT_VERSION, arrays, metadata)
    result = run_refused(["simulate", "--leader", "s.npz", "--follower", "bundled:fast",
                      "--duration", "5", "--out", "out"], tmp_path)  # fmt: skip
    assert one_line(result) == (
        "mirror-avatar: error: s.npz: the patient's and the target's generators differ in "
        "rate (100 Hz and 50 Hz)"
    )


@pytest.mark.parametrize("role", ["coach", "Leader", ""])
def test_a_cyber_player_of_an_unknown_role_is_refused(tmp_path: Path, role: str) -> None:
    player = CyberPlayer()
    player.initialise_q(0, 1.0)
    player.target_counts_ = np.ones(DEFAULT_BINS.n)
    player.training_ = {"role": role}
    player.save(tmp_path / "cyber.npz")
    result = run_refused(["simulate", "--leader", "cyber.npz", "--follower", "bundled:fast",
                      "--duration", "5", "--out", "out"], tmp_path)  # fmt: skip
    assert one_line(result) == (
        f"mirror-avatar: error: cyber.npz: training role '{role}' is none of "
        f"{', '.join(POLICY_ROLES)}"
    )


@pytest.mark.slow  # minutes of work: `make test-all` runs it
def test_identical_avatar_runs_write_identical_files(tmp_path: Path) -> None:
    (tmp_path / "trials").mkdir()
    for k, trial in enumerate(load_zhai2017()[9:12]):
        write_csv_trial(trial, tmp_path / "trials" / f"trial{k}.csv")
    for name in ("first.npz", "second.npz"):
        result = run_cli(["avatar", "create", "trials", "--name", "P", "--sessions", "2",
                          "--jobs", "1", "--out", name], tmp_path)  # fmt: skip
        assert result.returncode == 0, result.stderr
    first, second = (tmp_path / name for name in ("first.npz", "second.npz"))
    assert first.read_bytes() == second.read_bytes()
    assert "seconds" not in str(read_archive(first)[1])
    assert "seconds" in (tmp_path / "first.html").read_text()
