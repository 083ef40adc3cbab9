"""The registry of measures declares every key the measures return, once, with words and units."""

from __future__ import annotations

import numpy as np
import pytest

from mirror_avatar.lab.running.runner import headline_measures
from mirror_avatar.metrics import registry, session_metrics
from mirror_avatar.metrics.jitter import JITTER_BAND
from mirror_avatar.metrics.measures import MeasureOptions, coordination_statistics, session_measures
from mirror_avatar.sessions.session import Session
from mirror_avatar.testing import smooth_motion

RATE = 50.0


def session(n_players: int, seed: int = 0) -> Session:
    rng = np.random.default_rng(seed)
    x = np.array([smooth_motion(rng, 1000, RATE) for _ in range(n_players)])
    v = np.gradient(x, 1 / RATE, axis=1)
    times = np.arange(1000) / RATE
    return Session(times, x, v, np.zeros_like(x), np.full_like(x, np.nan))


def keys_of(values: dict) -> set[str]:
    return {k for k in values if k not in ("players", "surrogates")}


@pytest.mark.parametrize("n_players", [2, 3])
def test_every_key_the_measures_return_is_declared_once(n_players):
    s = session(n_players)
    found = session_metrics(s) | session_measures(s, options=MeasureOptions(n_surrogates=3)).values
    for key in keys_of(found):
        tested = registry.tested_of(key)
        assert tested is not None or registry.find(key) is not None, key
    for row in found.get("players", []):
        for key in set(row) - {"label", "neighbours"}:
            assert registry.find(key) is not None, key
    patterns = [m.key for m in registry.MEASURES]
    assert len(patterns) == len(set(patterns))


def test_the_metric_flag_names_exactly_what_session_metrics_returns():
    """`Measure.metric`, which `simulate` and `evaluate` print from, against the code."""
    returned = set()
    for n_players in (2, 3):
        metrics = session_metrics(session(n_players))
        returned |= {registry.find(key)[0].key for key in keys_of(metrics)}
        for row in metrics.get("players", []):
            returned |= {registry.find(key)[0].key for key in set(row) - {"label", "neighbours"}}
    declared = {m.key for m in registry.MEASURES if m.metric}
    assert declared - {"emd_target_{i}"} == returned  # only a cyber player has a target


def test_a_group_players_row_holds_exactly_the_group_player_measures():
    metrics = session_metrics(session(4))
    for row in metrics["players"]:
        assert set(row) - {"label", "neighbours"} == set(registry.GROUP_PLAYER)


def test_the_table_columns_cover_every_tabled_measure_once():
    columns = registry.TABLE_COLUMNS
    assert len(columns) == len(set(columns))
    for m in registry.MEASURES:
        if m.in_table and "{" not in m.key:
            assert m.key in columns
    assert {f"{c}_player_0" for c in registry.OWN_COLUMNS} <= {
        m.key.format(i=0, j=1) for m in registry.MEASURES
    }
    assert "transfer_entropy_0_to_1" in columns and "transfer_entropy_1_to_0" in columns


@pytest.mark.parametrize("n_players", [2, 3])
def test_the_measures_tested_are_those_the_surrogates_draw(n_players):
    s = session(n_players)
    drawn = coordination_statistics(s.positions, s.velocities, RATE, MeasureOptions())
    assert list(registry.measures_tested(n_players)) == list(drawn)
    values = session_measures(s, options=MeasureOptions(n_surrogates=3)).values
    p_keys = [k for k in values if k.endswith("_p_value")]
    assert p_keys == [registry.p_value_key(k) for k in registry.measures_tested(n_players)]


def test_a_p_value_named_after_another_measure_goes_both_ways():
    assert registry.p_value_key("max_cross_correlation") == "time_lag_p_value"
    assert registry.tested_of("time_lag_p_value") == "max_cross_correlation"
    assert registry.tested_of("rmse_p_value") == "rmse"
    assert registry.measures_tested(2)["rmse"] is False  # a smaller RMS is the more coordinated
    assert registry.tested_of("emd_players_p_value") is None  # not tested


def test_labels_fill_in_players_and_units_follow():
    assert registry.label("transfer_entropy_2_to_0") == "transfer entropy 2 -> 0"
    assert registry.heading("rmse") == "RMSE (units)"
    assert registry.heading("leader_lag_s") == "leader's lag (s)"
    band = f"{JITTER_BAND[0]:g}-{JITTER_BAND[1]:g} Hz"
    assert registry.label("jitter_index_player_1") == f"jitter index player 1 ({band} share)"
    with pytest.raises(KeyError):
        registry.label("no_such_measure")


def test_the_headline_opens_with_the_pair_and_group_coordination():
    assert registry.HEADLINE[:4] == ("phase_locking", "rmse", "mean_relative_phase", "time_lag")
    assert registry.is_headline("jitter_index_player_3")
    assert not registry.is_headline("sd_relative_phase")


def test_the_lab_console_lists_the_headline_measures_and_every_p_value():
    s = session(2)
    measures = session_measures(s, options=MeasureOptions(n_surrogates=3)).values
    listed = headline_measures(measures | {"error": "x"})
    assert {"leader", "co_confidence_rate", "transfer_entropy_1_to_0", "jitter_index_player_1",
            "time_lag_p_value", "surrogates", "error"} <= set(listed)  # fmt: skip
    assert not {"co_confidence_segments", "synchrony_share", "leadership_strength"} & set(listed)
