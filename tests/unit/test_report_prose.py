"""Numbers in a report's prose: p-values at the surrogates' floor, measures without a value."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mirror_avatar.cli.measure_options import format_measures
from mirror_avatar.metrics.measures import MeasureOptions
from mirror_avatar.metrics.surrogates import p_value
from mirror_avatar.signatures.permutations import p_text


@pytest.mark.parametrize(("n", "floor"), [(99, "0.01"), (19, "0.05"), (999, "0.001")])
def test_a_p_value_at_the_floor_is_an_upper_bound(n, floor) -> None:
    p = p_value(1.0, np.zeros(n))  # no surrogate as extreme: (1 + 0) / (1 + n)
    assert p == pytest.approx(1 / (n + 1))
    assert p_text(p, n) == f"p <= {floor}"


def test_a_p_value_above_the_floor_is_an_estimate() -> None:
    p = p_value(1.0, np.r_[np.zeros(97), 2.0, 3.0])  # two of 99 as extreme: 3 / 100
    assert p_text(p, 99) == "p = 0.03"
    assert p_text(1.0, 99) == "p = 1"


def test_no_p_value_is_said_in_words() -> None:
    assert p_text(p_value(math.nan, np.zeros(9)), 9) == "no p-value"


def measures(**changes: object) -> dict[str, object]:
    """The measures of a pair with no CC segment, as `evaluate_sessions` returns them."""
    values: dict[str, object] = {
        "co_confidence_rate": 0.0, "co_confidence_rate_p_value": 1.0,
        "co_confidence_count": 0, "co_confidence_mean_length": math.nan,
        "synchrony_share": 0.0, "synchrony_entries": 0, "synchrony_mean_dwell": math.nan,
        "leader": "none", "leader_share": 0.45, "leader_share_p_value": 0.05,
        "leader_lag_s": math.nan, "leadership_strength": 0.8,
        "leadership_strength_p_value": 0.01, "phase_locking_p_value": 0.01,
        "surrogates": {"kind": "shift", "n": 99, "min_shift": 2.0, "seed": 3757552657},
    }  # fmt: skip
    return values | changes


def test_measures_without_a_value_are_said_in_words() -> None:
    text = format_measures(measures(), MeasureOptions())
    assert "nan" not in text.lower()
    lines = dict(line.split("  ", 1) for line in text.splitlines() if "  " in line)
    assert lines["CC mean segment length"].strip() == "no segment"
    assert lines["mean dwell in synchrony"].strip() == "no episode"
    assert lines["leader's lag"].strip() == "no leader"


def test_a_session_without_a_leader_is_not_worded_as_one_with() -> None:
    text = format_measures(measures(), MeasureOptions(leader_share=0.6))
    assert "leader (none leads 60% of the windows)" in text
    assert "the leader leads" not in text
    assert "share of windows the most-leading player leads" in text


def test_p_values_at_the_floor_and_the_one_seed() -> None:
    text = format_measures(measures(), MeasureOptions(seed=7))
    assert "p <= 0.01" in text and "p = 0.01" not in text
    assert text.splitlines()[-1] == "(99 shift surrogates, --surrogate-seed 7)"
    assert "3757552657" not in text
