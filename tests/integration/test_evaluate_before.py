"""``evaluate`` writes today the files it wrote before its measures had one registry.

`tests/fixtures/evaluate_before/` holds sessions (bundled trials as a pair and a group, a
simulated dyad, a seeded lab trial) and the ``metrics.json`` and ``sessions.csv`` that
``evaluate`` wrote of them at commit 8afeb03 (its ``make.py``): every run is compared with them,
keys, text and structure exactly and numbers within the rounding another machine may give
(`snapshots.assert_close`), so computing each quantity once and trimming a session once changed
no number. Since a
session's surrogates are drawn from the seed it records (`mirror_avatar.metrics.measuring`),
the lab trial's surrogate seed, and with it one of its p-values, are the ones it records.
"""

from __future__ import annotations

import runpy
import shutil
from pathlib import Path

import pytest

from mirror_avatar.cli import main
from snapshots import LAST_DIGIT, assert_close, perturb_file, read_snapshot

FIXTURES = Path(__file__).parents[1] / "fixtures" / "evaluate_before"
RUNS = runpy.run_path(str(FIXTURES / "make.py"))["RUNS"]
"""The runs of the fixtures' ``make.py``: name -> evaluate's arguments."""

FILES = ("metrics.json", "sessions.csv")
"""The files of a run that are pinned, each as ``{name}_{file}`` in `FIXTURES`."""


def assert_wrote_as_before(out: Path, pinned: Path, name: str) -> None:
    """Assert that the files ``evaluate`` wrote into ``out`` are those of run ``name`` pinned in
    the folder ``pinned``."""
    for file in FILES:
        assert_close(read_snapshot(out / file), read_snapshot(pinned / f"{name}_{file}"), file)


@pytest.mark.parametrize("name", list(RUNS))
def test_evaluate_writes_what_it_wrote_before(name, tmp_path, monkeypatch, capsys):
    shutil.copytree(FIXTURES / "sessions", tmp_path / "sessions")
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", *RUNS[name], "--out", "out"]) == 0
    assert_wrote_as_before(tmp_path / "out", FIXTURES, name)


def pinned_copy(folder: Path, name: str, renamed: bool = False) -> Path:
    """Copy run ``name``'s pinned files into ``folder``, as evaluate names them if ``renamed``."""
    folder.mkdir()
    for file in FILES:
        shutil.copy(FIXTURES / f"{name}_{file}", folder / (file if renamed else f"{name}_{file}"))
    return folder


@pytest.mark.parametrize("name", list(RUNS))
@pytest.mark.parametrize("file", FILES)
def test_the_comparison_allows_rounding_and_catches_a_change(name, file, tmp_path):
    """The pinned file's numbers moved by their last digit pass, moved by relative 1e-6 fail.

    The pinned files stand for evaluate's output (on this machine they are the same, which the
    test above shows), compared with a copy of them where one file is perturbed.
    """
    out = pinned_copy(tmp_path / "out", name, renamed=True)
    rounded = pinned_copy(tmp_path / "rounded", name)
    perturb_file(rounded / f"{name}_{file}", LAST_DIGIT)
    assert (rounded / f"{name}_{file}").read_text() != (out / file).read_text()
    assert_wrote_as_before(out, rounded, name)
    changed = pinned_copy(tmp_path / "changed", name)
    perturb_file(changed / f"{name}_{file}", 1.0 + 1e-6)
    with pytest.raises(AssertionError):
        assert_wrote_as_before(out, changed, name)
