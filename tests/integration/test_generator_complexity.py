"""The codebook size chosen from a few trials, on the bundled data."""

from __future__ import annotations

import pytest

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.experiments import generator_complexity


@pytest.mark.slow  # minutes of work: `make test-all` runs it
def test_five_trials_generate_motion_as_close_as_the_persons_own() -> None:
    """Five trials of each style, the other four held out (one draw): the EMD of generated to
    held-out motion is at most 1.2 times the EMD between the person's own trials and the
    held-out ones, and every generated trial is identified as its style."""
    rows = generator_complexity.evaluate_complexity(load_zhai2017(), (5,), repeats=1, seed=0)
    chosen = [row for row in rows if row["method"] == "chosen (auto)"]
    assert {row["style"] for row in chosen} == {"fast", "slow"}
    for row in chosen:
        assert row["ratio"] <= 1.2, row
        assert row["identified"] == 1.0, row
        assert row["n_symbols"] in (8, 16, 32, 64, 128, 256)


def test_the_section_skips_data_without_two_styles() -> None:
    one_style = [t for t in load_zhai2017() if t.group == "fast"]
    section = generator_complexity.run(one_style, quick=True)
    assert section.tables == {} and "Skipped: it needs two styles" in section.text[-1]
