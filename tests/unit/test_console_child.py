"""The forked console child behaves as a fresh ``mirror-avatar`` process does."""

from __future__ import annotations

import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest

import mirror_avatar.cli
from console_child import run_console


def test_a_refusal_is_the_same_as_in_a_fresh_interpreter(tmp_path: Path) -> None:
    arguments = ["signature", "missing.csv", "--out", "out"]
    fresh = subprocess.run(
        [sys.executable, "-c", "from mirror_avatar.console import run; run()", *arguments],
        capture_output=True, text=True, check=False, cwd=tmp_path, timeout=300,
    )  # fmt: skip
    forked = run_console(arguments, tmp_path, timeout=300)
    assert fresh.returncode == forked.returncode == 2
    assert (fresh.stdout, fresh.stderr) == (forked.stdout, forked.stderr)
    assert "missing.csv" in forked.stderr


def test_a_warning_is_printed_with_the_default_filters_not_raised(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def warn_and_succeed() -> int:
        warnings.warn("overflow in a test", RuntimeWarning, stacklevel=1)
        warnings.warn("hidden by default", DeprecationWarning, stacklevel=1)
        print("done")
        return 0

    monkeypatch.setattr(mirror_avatar.cli, "main", warn_and_succeed)
    result = run_console([], tmp_path, timeout=300)
    assert (result.returncode, result.stdout) == (0, "done\n")
    assert "RuntimeWarning: overflow in a test" in result.stderr
    assert "hidden by default" not in result.stderr


def test_the_working_folder_and_environment_are_the_childs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def show() -> int:
        print(Path.cwd().name, os.environ.get("ONLY_HERE"), sys.argv)
        return 3

    monkeypatch.setattr(mirror_avatar.cli, "main", show)
    (tmp_path / "here").mkdir()
    result = run_console(["x"], tmp_path / "here", timeout=300, env={"ONLY_HERE": "1"})
    assert result.returncode == 3
    assert result.stdout == "here 1 ['mirror-avatar', 'x']\n"


def test_a_child_that_hangs_is_killed_at_the_deadline(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(mirror_avatar.cli, "main", lambda: time.sleep(600))
    with pytest.raises(subprocess.TimeoutExpired):
        run_console([], tmp_path, timeout=0.5)
