"""The virtual-trainer validation on the bundled real data (paper section VI-B).

Relative phase is partner minus VT: positive when the partner is ahead.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.experiments import EXPERIMENTS
from mirror_avatar.experiments.virtual_trainer import choose_styles, run
from mirror_avatar.files.atomic import json_safe
from mirror_avatar.files.trials import Trial
from mirror_avatar.report import Section


@pytest.fixture(scope="module")
def section(zhai_trials: list[Trial]) -> Section:
    return run(zhai_trials, quick=True, seed=0)


@pytest.fixture(scope="module")
def summary(section: Section) -> pd.DataFrame:
    (table,) = [t for caption, t in section.tables.items() if "against the paper" in caption]
    return table


@pytest.mark.long
def test_vt_follows_slow_people_closely(summary: pd.DataFrame) -> None:
    own = summary.loc["follows (slow people)"]
    assert own["sessions"] == 9
    assert own["cv"] >= 0.9
    assert own["rmse"] <= 0.12
    assert summary.loc["follows", "sessions"] == 18


def test_vt_lags_when_following_and_leads_when_leading(summary: pd.DataFrame) -> None:
    for row in ("follows (slow people)", "follows (fast people)", "follows"):
        assert summary.loc[row, "phase"] > 0
        assert summary.loc[row, "lag"] > 0
    assert summary.loc["leads", "phase"] < 0
    assert summary.loc["leads", "lag"] < 0


def test_vt_keeps_its_own_signature(summary: pd.DataFrame) -> None:
    for row in ("leads", "leads (same-style VT)", "follows (slow people)"):
        assert (
            summary.loc[row, "emd_reference_style (slow)"]
            < summary.loc[row, "emd_other_style (fast)"]
        )
    assert summary.loc["leads", "emd_own_reference"] < summary.loc["leads", "emd_partner"]


def test_section_contents(section: Section) -> None:
    assert section.key == "virtual_trainer"
    assert len(section.figures) == 4
    metrics = section.metrics
    assert metrics["seed"] == 0 and len(metrics["session_seeds"]) == 18 + 2 * 5
    assert len(metrics["follows"]) == 18 and len(metrics["leads"]) == 5
    assert len(metrics["leads_same_style"]) == 5
    json.dumps(json_safe(metrics), allow_nan=False)  # what metrics.json gets
    per_session = section.tables["Each recorded person as leader, the VT following"]
    assert np.all(per_session["cv"].between(0, 1))


def test_registered_after_the_generator() -> None:
    names = [name for name, _ in EXPERIMENTS]
    assert "virtual_trainer" in names
    earlier = "generator" if "generator" in names else "signature"
    assert names.index("virtual_trainer") > names.index(earlier)


def test_needs_two_groups(zhai_trials: list[Trial]) -> None:
    slow_only = [t for t in zhai_trials if t.group == "slow"]
    with pytest.raises(InputError, match="two groups of trials, found \\['slow'\\]"):
        run(slow_only, quick=True)
    with pytest.raises(InputError, match="two styles"):
        run(zhai_trials, quick=True, reference_style="slow", partner_style="medium")


def test_choose_styles_prefers_slow_and_fast_then_order_of_appearance(
    zhai_trials: list[Trial],
) -> None:
    assert choose_styles(zhai_trials) == ("slow", "fast")
    people = [replace(t, group=g) for t, g in zip(zhai_trials[:3], "bab", strict=True)]
    assert choose_styles(people) == ("b", "a")
    assert choose_styles(people, partner="b") == ("a", "b")
    assert choose_styles(zhai_trials, reference="fast") == ("fast", "slow")
