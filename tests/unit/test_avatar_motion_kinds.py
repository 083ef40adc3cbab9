"""An avatar and a cyber player carry a person's motion model of either kind, and read old files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mirror_avatar.files.model_files import save_model
from mirror_avatar.learning.acceleration_player import read_reference, reference_arrays
from mirror_avatar.learning.agent import CyberPlayer, load_cyber_player
from mirror_avatar.learning.discretisation import make_default_discretisation
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.motion.models import MotionModel
from mirror_avatar.motion.strokes import StrokeGenerator
from mirror_avatar.training.avatar import Avatar, load_avatar


@pytest.fixture(scope="module")
def strokes(zhai_trials_100hz) -> StrokeGenerator:
    return StrokeGenerator(random_state=5).fit(zhai_trials_100hz[9:12])


@pytest.fixture(scope="module")
def ims(zhai_trials_100hz) -> IMSGenerator:
    return IMSGenerator(n_symbols=16, random_state=5).fit(zhai_trials_100hz[9:11])


def untrained(role: str, reference: MotionModel | None = None) -> CyberPlayer:
    """A player with a fresh Q-table, marked as trained for ``role``."""
    features = "reference" if reference is not None else "relative"
    player = CyberPlayer(make_default_discretisation(features), reference=reference)
    player.initialise_q(0, 1.0)
    player.training_ = {"role": role, "seed": 0}
    return player


def make_avatar(generator: MotionModel) -> Avatar:
    players = {"follower": untrained("follower"), "leader": untrained("leader", generator)}
    return Avatar("P01", generator, players, {"generator": "test"})


def same_motion(a: MotionModel, b: MotionModel) -> None:
    assert type(a) is type(b)
    np.testing.assert_array_equal(a.sample_velocity(800, 3), b.sample_velocity(800, 3))


def test_an_avatar_with_a_stroke_generator_loads_back_moving_the_same(strokes, tmp_path):
    path = make_avatar(strokes).save(tmp_path / "avatar.npz")
    loaded = load_avatar(path)
    assert isinstance(loaded.generator, StrokeGenerator)
    same_motion(loaded.generator, strokes)
    leader = loaded.players["leader"]
    assert isinstance(leader.reference, StrokeGenerator) and leader.stochastic
    same_motion(leader.reference, strokes)
    with np.load(path, allow_pickle=False) as archive:
        metadata = json.loads(str(archive["metadata"]))
    assert metadata["generator"]["kind"] == "strokes"
    assert metadata["leader"]["reference"]["kind"] == "strokes"


def test_an_avatar_written_before_motion_kinds_loads_its_ims_generator(ims, tmp_path):
    """Files without a ``kind`` (the generator's or the reference's) hold IMS generators."""
    path = make_avatar(ims).save(tmp_path / "avatar.npz")
    with np.load(path, allow_pickle=False) as archive:
        arrays = {name: archive[name] for name in archive.files}
    metadata = json.loads(str(arrays.pop("metadata")))
    assert metadata["generator"].pop("kind") == "ims"
    assert metadata["leader"]["reference"].pop("kind") == "ims"
    for key in ("format", "version", "library_version"):
        metadata.pop(key, None)
    old = save_model(tmp_path / "old.npz", "mirror-avatar/avatar", 1, arrays, metadata)
    loaded = load_avatar(old)
    same_motion(loaded.generator, ims)
    assert isinstance(loaded.players["leader"].reference, IMSGenerator)
    same_motion(loaded.players["leader"].reference, ims)


def test_a_cyber_player_with_a_stroke_reference_saves_and_reads_it_back(strokes, tmp_path):
    player = untrained("leader", strokes)
    arrays, metadata = reference_arrays(player, "player")
    assert metadata["reference"]["kind"] == "strokes"
    same_motion(read_reference("player", arrays, metadata), strokes)
    loaded = load_cyber_player(player.save(tmp_path / "player.npz"))
    assert isinstance(loaded.reference, StrokeGenerator) and loaded.stochastic
    same_motion(loaded.reference, strokes)


def test_a_reference_without_a_kind_reads_as_ims(ims):
    arrays, metadata = reference_arrays(untrained("leader", ims), "player")
    del metadata["reference"]["kind"]
    same_motion(read_reference("player", arrays, metadata), ims)
