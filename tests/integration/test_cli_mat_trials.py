"""MATLAB files of many trials are refused from their header, before anything is expanded.

A struct element of a few compressed bytes becomes a trial of `MAT_DURATION` seconds, which
commands resample (6001 samples at 100 Hz): a small file of many elements expands to gigabytes.
The number of trials is read from the struct array's header first, so the refusal costs no
memory: the child process's peak resident memory (its own ``getrusage``, written at exit) stays
within a few megabytes of a command that refuses its input without reading it at all.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from mirror_avatar.files.trial_files import MAT_DURATION
from mirror_avatar.files.trial_io import MAX_MAT_TRIALS

SAFETY_TIMEOUT = 300
"""Seconds after which a child that still runs is killed."""

MARGIN_KB = 64 * 1024
"""Most peak memory (KiB) a refusal may take beyond refusing a file unread. Expanding the
trials below would take several times this."""

CHILD = (
    "import atexit, os, resource\n"
    "def peak():\n"
    "    with open(os.environ['PEAK_FILE'], 'w') as out:\n"
    "        out.write(str(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss))\n"
    "atexit.register(peak)\n"
    "from mirror_avatar.console import run\n"
    "run()\n"
)
"""The console entry point, writing its peak resident memory (KiB) to ``$PEAK_FILE`` at exit."""


def run_measured(
    arguments: list[str], folder: Path
) -> tuple[subprocess.CompletedProcess[str], int]:
    """Run the command line in a child; return its result and its peak memory (KiB)."""
    peak = folder / "peak.txt"
    result = subprocess.run(
        [sys.executable, "-c", CHILD, *arguments],
        capture_output=True,
        text=True,
        check=False,
        cwd=folder,
        env=dict(os.environ) | {"PEAK_FILE": str(peak)},
        timeout=SAFETY_TIMEOUT,
    )
    return result, int(peak.read_text())


def struct_file(path: Path, n_trials: int, samples: int) -> Path:
    """A compressed MATLAB file of ``n_trials`` struct elements of ``samples`` zero positions."""
    trials = np.empty((1, n_trials), dtype=[("x", object), ("v", object)])
    column = np.zeros((samples, 1))
    for k in range(n_trials):
        trials[0, k] = (column, column)
    scipy.io.savemat(path, {"trials": trials}, do_compression=True)
    return path


def refused_unread(arguments: list[str], folder: Path) -> int:
    """Peak memory (KiB) of the same command refusing a FIFO it never reads."""
    fifo = folder / "unread.mat"
    os.mkfifo(fifo)
    result, peak = run_measured([a.replace("trials.mat", fifo.name) for a in arguments], folder)
    assert result.returncode == 2 and "named pipe" in result.stderr, result.stderr
    return peak


@pytest.mark.slow  # minutes of work: `make test-all` runs it
def test_too_many_trials_for_generator_fit_are_refused_before_expansion(tmp_path: Path) -> None:
    n_trials = 3 * MAX_MAT_TRIALS
    path = struct_file(tmp_path / "trials.mat", n_trials, samples=int(MAT_DURATION) + 1)
    assert path.stat().st_size < 1_000_000
    arguments = ["generator", "fit", "trials.mat", "--out", "model.npz"]
    result, peak = run_measured(arguments, tmp_path)
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip() == (
        f"mirror-avatar: error: trials.mat: holds {n_trials:,} trials (struct elements), more "
        f"than the {MAX_MAT_TRIALS:,} read from one MATLAB file: split it into several files"
    )
    expanded_kb = n_trials * (MAT_DURATION * 100 + 1) * 8 // 1024
    assert expanded_kb > 2 * MARGIN_KB
    assert peak - refused_unread(arguments, tmp_path) < MARGIN_KB
    assert not (tmp_path / "model.npz").exists()


@pytest.mark.long
def test_vt_on_a_file_of_several_trials_is_refused_from_the_header(tmp_path: Path) -> None:
    samples = 12_000_000
    path = struct_file(tmp_path / "trials.mat", 2, samples)
    assert path.stat().st_size < 2_000_000
    arguments = ["simulate", "--leader", "vt:trials.mat", "--follower", "bundled:fast",
                 "--duration", "5", "--out", "out"]  # fmt: skip
    result, peak = run_measured(arguments, tmp_path)
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip() == "mirror-avatar: error: trials.mat: holds 2 trials, expected one"
    assert 2 * samples * 8 // 1024 > 2 * MARGIN_KB
    assert peak - refused_unread(arguments, tmp_path) < MARGIN_KB
