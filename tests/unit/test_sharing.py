"""Shareable stroke models (`mirror_avatar.motion.sharing`): strokes averaged in groups by MDAV,
from which the training trials cannot be rebuilt; the avatar and the commands that write them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.learning.discretisation import make_default_discretisation
from mirror_avatar.motion.models import load_motion
from mirror_avatar.motion.sharing import (
    blended_profile,
    mdav_groups,
    rebuild_errors,
    shareable,
)
from mirror_avatar.motion.strokes import StrokeGenerator, reversals
from mirror_avatar.training.avatar import Avatar, load_avatar, shareable_avatar

FITTED = 5
"""Trials of a bundled style fitted; the other four are held out."""


@pytest.fixture(scope="module")
def slow() -> tuple[list, list]:
    trials = [t for t in load_zhai2017() if t.group == "slow"]
    return trials[:FITTED], trials[FITTED:]


@pytest.fixture(scope="module")
def fitted(slow) -> StrokeGenerator:
    return StrokeGenerator(random_state=0).fit(slow[0])


def test_mdav_finds_clusters_of_exactly_k_points() -> None:
    """Twelve tight clusters of three far apart (known truth): each group is one cluster."""
    rng = np.random.default_rng(0)
    centres = rng.uniform(-100, 100, size=(12, 4))
    points = np.repeat(centres, 3, axis=0) + rng.normal(scale=0.01, size=(36, 4))
    groups = mdav_groups(points, 3)
    assert sorted(sorted(g.tolist()) for g in groups) == [[3 * c, 3 * c + 1, 3 * c + 2] for c in
                                                          range(12)]  # fmt: skip


@pytest.mark.parametrize(("n", "k"), [(3, 3), (5, 3), (17, 3), (100, 7), (41, 2)])
def test_mdav_partitions_every_point_into_groups_of_k_to_2k_minus_1(n: int, k: int) -> None:
    points = np.random.default_rng(n).normal(size=(n, 3))
    groups = mdav_groups(points, k)
    assert sorted(np.concatenate(groups).tolist()) == list(range(n))
    assert all(k <= g.size <= 2 * k - 1 for g in groups)


def test_a_blended_profile_keeps_its_members_detail_and_runs_from_0_to_1() -> None:
    """Three ramps with independent fine detail (SD 0.01, white): the blend's detail keeps its
    SD (within 15 %) where the mean's is divided by sqrt(3); the smooth part is the ramp."""
    rng = np.random.default_rng(0)
    ramp = np.linspace(0.0, 1.0, 4001)
    profiles = ramp + rng.normal(scale=0.01, size=(3, ramp.size))
    blended = blended_profile(profiles, np.array([1.0, -1.0, 1.0]))
    assert blended[0] == pytest.approx(0.0, abs=1e-12)
    assert blended[-1] == pytest.approx(1.0, abs=1e-12)
    assert np.std(blended - ramp) == pytest.approx(0.01 * np.sqrt(8 / 9), rel=0.15)
    assert np.std(profiles.mean(axis=0) - ramp) == pytest.approx(0.01 / np.sqrt(3), rel=0.15)


def test_a_shared_model_averages_each_stroke_over_a_group_of_its_direction(fitted) -> None:
    shared = shareable(fitted, 3)
    assert fitted.lengths_.size // 5 <= shared.lengths_.size <= fitted.lengths_.size // 3
    for direction in (-1.0, 1.0):
        ups = np.sum(np.sign(fitted.displacements_) == direction)
        assert ups // 5 <= np.sum(np.sign(shared.displacements_) == direction) <= ups // 3
    assert np.median(shared.lengths_) == pytest.approx(np.median(fitted.lengths_), rel=0.15)
    assert np.all(shared.bandwidth_ >= fitted.bandwidth_)
    assert "labels" not in shared.training_summary_
    assert shared.training_summary_["holds"] == "averages of 3 or more strokes"
    positions = shared.sample_positions(3000, 4)
    assert np.all(np.abs(positions) <= 0.5) and np.array_equal(
        positions, shared.sample_positions(3000, 4)
    )


@pytest.mark.long
def test_the_training_trials_cannot_be_rebuilt_from_a_shared_model(slow, fitted) -> None:
    """The fitted model rebuilds every training stroke exactly; the shared one rebuilds them no
    better than the held-out trials' strokes (median error at least 0.75 x; measured 0.90 on
    the slow style, 1.05 on the fast one)."""
    fitted_trials, held = slow
    assert np.max(rebuild_errors(fitted, fitted_trials)) < 1e-12
    assert np.median(rebuild_errors(fitted, held)) > 0.005
    shared = shareable(fitted, 3)
    training, fresh = rebuild_errors(shared, fitted_trials), rebuild_errors(shared, held)
    assert np.median(training) >= 0.75 * np.median(fresh)
    assert np.mean(training < 1e-6) == 0.0


def test_a_shared_model_moves_like_the_fitted_one(slow, fitted) -> None:
    """Generated strokes' median length and size, and the SD of their logarithms (the spread
    the averaging takes away and the jitter adds back), within 15 % of the fitted model's."""
    shared = shareable(fitted, 3)

    def strokes(model: StrokeGenerator) -> list[float]:
        positions = model.sample_positions(30000, 1)
        edges = reversals(positions, model.min_reversal)[1:-1]
        lengths, sizes = np.diff(edges), np.abs(np.diff(positions[edges]))
        return [np.median(lengths), np.median(sizes), np.log(lengths).std(), np.log(sizes).std()]

    assert strokes(shared) == pytest.approx(strokes(fitted), rel=0.15)


def test_too_few_strokes_or_a_group_of_one_are_refused(fitted) -> None:
    with pytest.raises(InputError, match="at least 2"):
        shareable(fitted, 1)
    with pytest.raises(InputError, match="lower --group-size"):
        shareable(fitted, 10_000)


def test_a_shared_model_saves_and_loads_and_a_shared_model_shares_again(fitted, tmp_path) -> None:
    shared = shareable(fitted, 3)
    shared.save(tmp_path / "shared.npz")
    loaded = load_motion(tmp_path / "shared.npz")
    assert isinstance(loaded, StrokeGenerator)
    assert np.array_equal(loaded.sample_positions(500, 2), shared.sample_positions(500, 2))
    assert loaded.training_summary_["holds"] == "averages of 3 or more strokes"
    again = shareable(loaded, 2)
    assert again.lengths_.size < loaded.lengths_.size
    assert again.training_summary_["n_trials"] == FITTED


def untrained_avatar(generator: StrokeGenerator) -> Avatar:
    """An avatar of fresh Q-tables, its leader reading the generator as its reference."""
    players = {}
    for role, reference in (("follower", None), ("leader", generator)):
        features = "reference" if reference is not None else "relative"
        players[role] = CyberPlayer(make_default_discretisation(features), reference=reference)
        players[role].initialise_q(0, 1.0)
        players[role].training_ = {"role": role, "seed": 0}
    return Avatar("P01", generator, players, {"trials": ["a", "b"]})


def test_a_shared_avatar_keeps_its_policies_and_reads_the_shared_model(fitted, tmp_path) -> None:
    avatar = untrained_avatar(fitted)
    shared = shareable_avatar(avatar, 3)
    shared.save(tmp_path / "shared.npz")
    loaded = load_avatar(tmp_path / "shared.npz")
    assert loaded.summary["trials"] == 2
    assert loaded.generator.training_summary_["holds"] == "averages of 3 or more strokes"
    assert np.array_equal(loaded.players["leader"].reference.lengths_, shared.generator.lengths_)
    for role in ("follower", "leader"):
        assert np.array_equal(loaded.players[role].q_table_, avatar.players[role].q_table_)
    assert avatar.generator is fitted and avatar.players["leader"].reference is fitted


def test_generator_share_writes_a_shareable_file_and_refuses_an_ims_model(
    fitted, tmp_path: Path, capsys
) -> None:
    fitted.save(tmp_path / "person.npz")
    out = tmp_path / "shared.npz"
    assert main(["generator", "share", str(tmp_path / "person.npz"), "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "no trial can be rebuilt" in said and str(out) in said
    assert load_motion(out).training_summary_["holds"] == "averages of 3 or more strokes"
    ims = tmp_path / "ims.npz"
    assert main(["generator", "fit", "--bundled", "slow", "--kind", "ims", "--symbols", "16",
                 "--no-likeness", "--out", str(ims)]) == 0  # fmt: skip
    assert main(["generator", "share", str(ims), "--out", str(tmp_path / "x.npz")]) == 2
    assert "only a stroke generator can be shared" in capsys.readouterr().err
    assert not (tmp_path / "x.npz").exists()


def test_avatar_share_writes_the_avatar_shared(fitted, tmp_path: Path, capsys) -> None:
    untrained_avatar(fitted).save(tmp_path / "P01.npz")
    out = tmp_path / "P01-shared.npz"
    assert main(["avatar", "share", str(tmp_path / "P01.npz"), "--out", str(out),
                 "--group-size", "4"]) == 0  # fmt: skip
    assert "no trial can be rebuilt" in capsys.readouterr().out
    holds = load_avatar(out).generator.training_summary_["holds"]
    assert holds == "averages of 4 or more strokes"
