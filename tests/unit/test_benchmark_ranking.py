"""The benchmark's rankings, checked against distances worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from mirror_avatar.cli.benchmark import split_specs
from mirror_avatar.common.errors import InputError
from mirror_avatar.experiments.benchmark_ranking import (
    FLOORS,
    HUMAN_MEASURES,
    parse_criterion,
    rank_by_humans,
    rank_by_measure,
)
from mirror_avatar.experiments.partner_benchmark import HUMAN, SCORES, BenchmarkResult


def result(rows: list[tuple[str, dict[str, float]]]) -> BenchmarkResult:
    """A benchmark result whose trials hold the given scores (every other score 0.5)."""
    trials = [
        {"follower": name, "trial": f"t{k}", "group": ""} | dict.fromkeys(SCORES, 0.5) | scores
        for k, (name, scores) in enumerate(rows)
    ]
    return BenchmarkResult(pd.DataFrame(trials), {})


def test_closeness_to_humans_is_the_rms_of_differences_over_the_humans_spread() -> None:
    """Two humans (rms 0.10 and 0.14, lag 0.2 and 0.3 s); two followers, each on one trial.

    Humans' means 0.12 and 0.25 s, standard deviations (ddof 1) 0.02 * sqrt(2) = 0.028284 and
    0.05 * sqrt(2) = 0.070711. Follower a (rms 0.12, lag 0.60): z = 0 and 4.9497, d = 3.5.
    Follower b (rms 0.18, lag 0.25): z = 2.1213 and 0, d = 1.5. So b comes first.
    """
    found = result(
        [
            (HUMAN, {"rms": 0.10, "time_lag": 0.2}),
            (HUMAN, {"rms": 0.14, "time_lag": 0.3}),
            ("a", {"rms": 0.12, "time_lag": 0.60}),
            ("b", {"rms": 0.18, "time_lag": 0.25}),
        ]
    )
    ranking = rank_by_humans(found, ("rms", "time_lag"))
    assert ranking.order() == ["b", "a"]
    assert ranking.table.loc["a", "distance"] == pytest.approx(3.5)
    assert ranking.table.loc["b", "distance"] == pytest.approx(1.5)
    assert ranking.table.loc["a", "z_time_lag"] == pytest.approx(0.35 / (0.05 * math.sqrt(2)))
    assert ranking.humans.loc["scale", "rms"] == pytest.approx(0.02 * math.sqrt(2))
    assert "humans" in ranking.describe() and "rms, time_lag" in ranking.describe()


def test_a_tiny_human_spread_is_floored() -> None:
    """Humans agreeing to 1e-6 on the EMD are divided by the floor, not by 1e-6."""
    found = result(
        [
            (HUMAN, {"emd": 0.020}),
            (HUMAN, {"emd": 0.020001}),
            ("a", {"emd": 0.030}),
        ]
    )
    ranking = rank_by_humans(found, ("emd",))
    assert ranking.humans.loc["scale", "emd"] == FLOORS["emd"]
    assert ranking.table.loc["a", "distance"] == pytest.approx(0.0099995 / FLOORS["emd"])


def test_a_follower_lacking_a_measure_comes_last() -> None:
    """A follower that never moves has no phase locking: it is ranked after the others."""
    found = result(
        [
            (HUMAN, {"phase_locking": 0.8}),
            (HUMAN, {"phase_locking": 0.9}),
            ("still", {"phase_locking": math.nan}),
            ("far", {"phase_locking": 0.1}),
        ]
    )
    ranking = rank_by_humans(found, ("phase_locking",))
    assert ranking.order() == ["far", "still"]
    assert np.isnan(ranking.table.loc["still", "distance"])


def test_one_human_recording_is_refused() -> None:
    found = result([(HUMAN, {}), ("a", {})])
    with pytest.raises(InputError, match="--humans: 1 recording"):
        rank_by_humans(found, HUMAN_MEASURES)


def test_one_measure_ranks_by_its_ideal() -> None:
    """Phase locking nearest 1 first; amplitude ratio nearest 1 whichever side; RMS nearest 0."""
    found = result(
        [
            ("a", {"phase_locking": 0.7, "amplitude_ratio": 1.8, "rms": 0.3}),
            ("b", {"phase_locking": 0.9, "amplitude_ratio": 0.5, "rms": 0.1}),
            ("c", {"phase_locking": 0.2, "amplitude_ratio": 1.1, "rms": 0.2}),
        ]
    )
    assert rank_by_measure(found, "phase_locking").order() == ["b", "a", "c"]
    assert rank_by_measure(found, "amplitude_ratio").order() == ["c", "b", "a"]
    ranking = rank_by_measure(found, "rms")
    assert ranking.order() == ["b", "c", "a"]
    assert ranking.table["distance"].tolist() == pytest.approx([0.1, 0.2, 0.3])


@pytest.mark.parametrize(
    ("text", "humans", "expected"),
    [
        ("humans", True, ("humans", HUMAN_MEASURES)),
        ("humans:rms, emd", True, ("humans", ("rms", "emd"))),
        ("rpe", False, ("rpe", ("rpe",))),
        ("phase_locking", True, ("phase_locking", ("phase_locking",))),
    ],
)
def test_rank_by_is_read(text: str, humans: bool, expected: tuple) -> None:
    assert parse_criterion(text, humans) == expected


@pytest.mark.parametrize(
    ("text", "humans", "message"),
    [
        ("humans", False, "--rank-by: humans needs recorded human followers: give --humans"),
        ("humans:rms,cv", True, "--rank-by: unknown measure cv; measures are rms"),
        ("humans:", True, "--rank-by: unknown measure (none)"),
        ("cv", False, "--rank-by: unknown criterion 'cv'; give humans"),
        ("rms:2", False, "--rank-by: unknown criterion 'rms:2'"),
    ],
)
def test_bad_rank_by_is_one_line(text: str, humans: bool, message: str) -> None:
    with pytest.raises(InputError) as error:
        parse_criterion(text, humans)
    assert str(error.value).startswith(message) and "\n" not in str(error.value)


@pytest.mark.parametrize(
    ("values", "expected"),
    [
        (("adaptive,rpc",), ["adaptive", "rpc"]),
        (("adaptive:cp=30,delta=0.2,rpc",), ["adaptive:cp=30,delta=0.2", "rpc"]),
        (("hkb:a=-1,b=-5", "P5.npz, vt"), ["hkb:a=-1,b=-5", "P5.npz", "vt"]),
        (("rpc,k=3",), ["rpc", "k=3"]),
        (("P5.npz,,bundled:slow",), ["P5.npz", "bundled:slow"]),
    ],
)
def test_models_are_split_at_the_commas_between_specs(values: tuple, expected: list) -> None:
    assert split_specs(values) == expected
