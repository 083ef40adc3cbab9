"""The group experiment: a cyber player among four virtual trainers on random graphs."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from mirror_avatar.experiments import EXPERIMENTS
from mirror_avatar.experiments.group import MEASURES, check_criteria, choose_members, run
from mirror_avatar.files.atomic import json_safe
from mirror_avatar.files.trials import Trial
from mirror_avatar.report import Section


@pytest.fixture(scope="module")
def section(zhai_trials: list[Trial]) -> Section:
    return run(zhai_trials, quick=True, seed=1, n_sessions=60)


@pytest.mark.long
def test_quick_group_validation_runs_end_to_end(section: Section) -> None:
    assert section.key == "group" and len(section.figures) == 5
    metrics = section.metrics
    assert metrics["target"] == "VT5" and metrics["training_sessions"] == 60
    records = pd.DataFrame(metrics["records"])
    assert len(records) == 2 * metrics["validation_sessions"]
    assert set(records["player"]) == {"VT5", "cyber player"}
    for key in MEASURES:
        assert np.all(np.isfinite(records[key]))
    assert records["phase_locking"].between(0, 1).all()
    assert set(metrics["topologies"]) == {"complete", "ring", "path", "star"}
    baselines = metrics["baselines_rms"]
    assert baselines["trained"] < baselines["untrained (random Q)"]
    json.dumps(json_safe(metrics), allow_nan=False)


def test_virtual_trainers_synchronise_and_the_ends_of_a_path_less(section: Section) -> None:
    synchrony = section.metrics["per_player_synchronisation"]
    assert synchrony["complete"]["group (mean rho_g)"] > 0.8
    path = synchrony["path"]
    assert max(path["player 0"], path["player 3"]) < min(path["player 1"], path["player 2"])


@pytest.mark.long
def test_paired_sessions_share_the_graph_and_the_partners(zhai_trials: list[Trial]) -> None:
    """Replacing the target changes nothing else: the first sample of every partner agrees."""
    from mirror_avatar.experiments.group import compare
    from mirror_avatar.sessions.graphs import random_connected_graph
    from mirror_avatar.training.cast import cast_virtual_trainers
    from mirror_avatar.training.imitation import make_group, make_group_cyber_player

    cast = cast_virtual_trainers(zhai_trials, n_symbols=32)
    generators = [cast.trainers[i].generator for i in choose_members(cast)]
    group = make_group(generators[-1], generators[:-1])
    player = make_group_cyber_player()
    player.initialise_q(0, 1e-3)
    _, (with_vt, with_cyber) = compare(group, "VT5", player, [5], random_connected_graph)
    np.testing.assert_array_equal(with_vt.graph, with_cyber.graph)
    np.testing.assert_array_equal(with_vt.references[:-1], with_cyber.references[:-1])
    np.testing.assert_array_equal(with_vt.positions[:-1, :2], with_cyber.positions[:-1, :2])


@pytest.mark.long
def test_members_of_the_bundled_cast_and_of_three_people(zhai_trials: list[Trial]) -> None:
    """Bundled: VT1 (fast), VT4, VT6, then the target VT5; three people: all, the target last."""
    from mirror_avatar.training.cast import cast_virtual_trainers

    bundled = cast_virtual_trainers(zhai_trials, n_symbols=16)
    assert [bundled.trainers[i].label for i in choose_members(bundled)] == [
        "VT1", "VT4", "VT6", "VT5"
    ]  # fmt: skip
    people = [replace(t, group=name) for t, name in zip(zhai_trials[:9], "aaabbbccc", strict=True)]
    cast = cast_virtual_trainers(people, n_symbols=16)
    assert cast.whole_people and [t.label for t in cast.trainers] == ["a", "b", "c"]
    assert [cast.trainers[i].label for i in choose_members(cast)] == ["a", "c", "b"]


def test_criteria_by_hand() -> None:
    rows = []
    for k in range(4):
        rows.append({"session": k, "player": "VT5", "phase_locking": 0.80 + 0.01 * k,
                     "group_synchronisation": 0.85, "rmse": 0.05 + 0.01 * k})  # fmt: skip
        rows.append({"session": k, "player": "cyber player", "phase_locking": 0.84 + 0.01 * k,
                     "group_synchronisation": 0.86, "rmse": 0.05 + 0.02 * k})  # fmt: skip
    checks = check_criteria(pd.DataFrame(rows))
    assert checks["phase_locking difference"] == pytest.approx(0.04)
    assert not checks["phase_locking within"] and checks["group_synchronisation within"]
    assert checks["rmse SD ratio"] == pytest.approx(2.0)
    assert not checks["rmse SD within"]  # the SD is twice the target's: over the 1.5 limit
    assert not checks["all"]


def test_registered_after_the_dyads() -> None:
    names = [name for name, _ in EXPERIMENTS]
    assert names.index("group") == names.index("cyber_player") + 1
