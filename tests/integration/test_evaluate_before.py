"""``evaluate`` writes today the files it wrote before its measures had one registry.

`tests/fixtures/evaluate_before/` holds sessions (bundled trials as a pair and a group, a
simulated dyad, a seeded lab trial) and the ``metrics.json`` and ``sessions.csv`` that
``evaluate`` wrote of them at commit 8afeb03 (its ``make.py``): every run is compared byte for
byte, so computing each quantity once and trimming a session once changed no number. Since a
session's surrogates are drawn from the seed it records (`mirror_avatar.metrics.measuring`),
the lab trial's surrogate seed, and with it one of its p-values, are the ones it records.
"""

from __future__ import annotations

import runpy
import shutil
from pathlib import Path

import pytest

from mirror_avatar.cli import main

FIXTURES = Path(__file__).parents[1] / "fixtures" / "evaluate_before"
RUNS = runpy.run_path(str(FIXTURES / "make.py"))["RUNS"]
"""The runs of the fixtures' ``make.py``: name -> evaluate's arguments."""


@pytest.mark.parametrize("name", list(RUNS))
def test_evaluate_writes_what_it_wrote_before(name, tmp_path, monkeypatch, capsys):
    shutil.copytree(FIXTURES / "sessions", tmp_path / "sessions")
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", *RUNS[name], "--out", "out"]) == 0
    for file in ("metrics.json", "sessions.csv"):
        expected = (FIXTURES / f"{name}_{file}").read_bytes()
        assert (tmp_path / "out" / file).read_bytes() == expected, file
