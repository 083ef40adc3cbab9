"""Tests of the player implementations and of the conformance check."""

import math

import numpy as np
import pytest

from mirror_avatar.dynamics import FOLLOWER, JOINT, LEADER
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.players import (
    Observation,
    Player,
    PlayerCheckError,
    RecordedPlayer,
    VirtualTrainer,
    check_player,
    draw_reference,
)
from mirror_avatar.players.reference import ReferenceDraw, draw_references, interpolate_on_grid

STILL = Observation.of_partner(0, 0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def generator(zhai_trials_100hz: list) -> IMSGenerator:
    return IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[9:12])


@pytest.mark.parametrize("params", [LEADER, FOLLOWER, JOINT])
def test_virtual_trainer_with_a_generator_passes_the_check(generator, params) -> None:
    check_player(lambda: VirtualTrainer(params, generator))


def test_virtual_trainer_with_a_recorded_reference_passes_the_check(zhai_trials_100hz) -> None:
    check_player(lambda: VirtualTrainer(FOLLOWER, zhai_trials_100hz[0]))


def test_recorded_player_passes_the_check(zhai_trials) -> None:
    check_player(lambda: RecordedPlayer(zhai_trials[3]))


class _Drifting(Player):
    """A player that leaves the playing range."""

    def reset(self, seed=None):
        self.x = 0.0
        return self.x, 0.0

    def step(self, observation):
        self.x += 0.01
        return self.x, 0.3


class _Forgetful(_Drifting):
    """A stochastic player that ignores its seed."""

    stochastic = True

    def step(self, observation):
        return 0.0, 0.0


class _Lonely(_Forgetful):
    """A player that fails when it has no neighbour."""

    stochastic = False

    def step(self, observation):
        return float(observation.positions[0]), 0.0


class _Sloppy(_Forgetful):
    """A player that reports its control as a string."""

    stochastic = False
    last_control = "none"


class _Undeclared:
    """Not a Player at all."""

    period = 0.03


@pytest.mark.parametrize(
    ("factory", "fragment"),
    [
        (_Drifting, "range"),
        (_Forgetful, "seed"),
        (_Lonely, "failed with 0 neighbours"),
        (_Sloppy, "last_control must be a float"),
        (_Undeclared, "not a mirror_avatar.players.Player"),
    ],
)
def test_the_check_catches_broken_players(factory, fragment) -> None:
    with pytest.raises(PlayerCheckError, match=fragment):
        check_player(factory)


def test_references_extend_consistently(generator) -> None:
    short = draw_reference(generator, 3000, 0.03, np.random.default_rng(4))
    long = draw_reference(generator, 7000, 0.03, np.random.default_rng(4))
    np.testing.assert_array_equal(short, long[:3000])
    trainer = VirtualTrainer(LEADER, generator)
    trainer.reset(seed=4)
    steps = [trainer.step(STILL) and trainer.last_reference for _ in range(2500)]
    np.testing.assert_array_equal(steps, long[:2500])


def test_references_drawn_together_equal_each_drawn_alone(generator, zhai_trials_100hz) -> None:
    other = IMSGenerator(n_symbols=16, random_state=1).fit(zhai_trials_100hz[3:5])
    draws = [
        ReferenceDraw(source, n_steps, period, seed)
        for seed, (source, n_steps, period) in enumerate(
            [(generator, 2000, 0.03)] * 11
            + [(other, 2000, 0.03)] * 3
            + [(generator, 2500, 0.03), (generator, 700, 0.01), (zhai_trials_100hz[0], 900, 0.03)]
        )
    ]
    together = draw_references(draws)
    for draw, reference in zip(draws, together, strict=True):
        alone = draw_reference(
            draw.source, draw.n_steps, draw.period, np.random.default_rng(draw.random_state)
        )
        np.testing.assert_array_equal(reference, alone)
        assert reference.shape == (draw.n_steps,)


@pytest.mark.parametrize(
    ("rate", "period", "n", "m"),
    [(100.0, 0.03, 650, 300), (15.0, 0.03, 100, 400), (60.0, 1 / 60, 200, 120)],
)
def test_interpolation_on_a_uniform_grid_is_numpys(rate, period, n, m, rng) -> None:
    values, times = rng.normal(size=n), np.arange(m) * period
    grid = np.arange(n) / rate
    expected = np.interp(times, grid, values)
    np.testing.assert_array_equal(interpolate_on_grid(times, grid, rate, values), expected)


def test_recorded_reference_is_the_trial_velocity(zhai_trials_100hz) -> None:
    trial = zhai_trials_100hz[0]
    reference = draw_reference(trial, 100, 0.03, np.random.default_rng(0))
    expected = np.interp(np.arange(100) * 0.03, trial.times - trial.times[0], trial.velocity())
    np.testing.assert_allclose(reference, expected)


def test_recorded_player_replays_and_holds_at_the_end(zhai_trials_100hz) -> None:
    trial = zhai_trials_100hz[0]
    player = RecordedPlayer(trial)
    assert player.reset()[0] == pytest.approx(trial.positions[0])
    positions = [player.step(STILL)[0] for _ in range(3000)]
    assert positions[99] == pytest.approx(
        np.interp(3.0, trial.times - trial.times[0], trial.positions)
    )
    assert positions[-1] == positions[-2]


def test_follower_predicts_the_partner_by_constant_velocity(generator) -> None:
    """Against a partner moving at constant velocity the follower ends up on top of it."""
    follower = VirtualTrainer(FOLLOWER.with_(theta_p=0.99), generator)
    follower.reset(seed=0)
    x = 0.0
    for k in range(300):
        x, _ = follower.step(
            Observation.of_partner(k, -0.3 + 0.002 * k, 0.002 / 0.03, -0.3 + 0.002 * (k - 1))
        )
    assert x == pytest.approx(-0.3 + 0.002 * 300, abs=0.02)
    assert not math.isnan(follower.last_control)


def test_a_group_is_seen_through_its_mean(generator) -> None:
    """Neighbours at the same mean state give the same step as one partner there."""
    group = Observation(5, np.array([0.1, 0.3]), np.array([0.5, -0.1]), np.array([0.09, 0.31]))
    single = Observation.of_partner(5, 0.2, 0.2, 0.2)
    trainers = [VirtualTrainer(JOINT, generator) for _ in range(2)]
    for trainer in trainers:
        trainer.reset(seed=3)
    assert trainers[0].step(group) == trainers[1].step(single)
