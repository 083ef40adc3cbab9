"""After the warm-up, a person's first command loads every kernel it needs: it compiles nothing."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from mirror_avatar.files.trial_io import write_csv_trial
from mirror_avatar.files.trials import Trial
from mirror_avatar.warm_up import warm_up

COUNT_COMPILATIONS = """
import sys

from numba.core import event

from mirror_avatar.cli import main


class Compilations(event.Listener):
    def __init__(self):
        self.names = set()

    def on_start(self, started):
        self.names.add(started.data["dispatcher"].py_func.__qualname__)

    def on_end(self, ended):
        pass


compilations = Compilations()
event.register("numba:compile", compilations)
code = main(sys.argv[1:])
print("compiled:", sorted(compilations.names))
sys.exit(code)
"""
"""A fresh process running the command line with every compilation numba starts recorded."""


def compilations(command: list[str]) -> str:
    """Run ``command`` in a fresh process; return its line naming what numba compiled."""
    done = subprocess.run(
        [sys.executable, "-c", COUNT_COMPILATIONS, *command],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.splitlines()[-1]


@pytest.mark.long
def test_a_first_generator_fit_compiles_no_kernel(zhai_trials: list[Trial], tmp_path: Path) -> None:
    warm_up()
    folder = tmp_path / "person"
    folder.mkdir()
    for trial in zhai_trials[:3]:
        write_csv_trial(trial, folder / f"{trial.label}.csv")
    command = [
        "generator",
        "fit",
        str(folder),
        "--kind",
        "ims",
        "--symbols",
        "8",
        "--out",
        str(tmp_path / "m.npz"),
    ]
    assert compilations(command) == "compiled: []"


@pytest.mark.long
def test_model_partners_in_a_fresh_process_compile_no_kernel(tmp_path: Path) -> None:
    """The models' shared integrator, given each model's rates, is loaded from the cache too."""
    warm_up()
    for leader, follower in (("kuramoto", "rpc"), ("excitator", "hkb")):
        command = ["simulate", "--leader", leader, "--follower", follower, "--duration", "2",
                   "--out", str(tmp_path / follower)]  # fmt: skip
        assert compilations(command) == "compiled: []"
