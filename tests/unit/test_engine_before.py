"""Two-player sessions replayed against those recorded before the N-player engine.

`tests/fixtures/engine_before/` holds sessions, the generators they used and the training
results recorded with commit c9581d4 (see its ``make.py``); here the current engine replays them.
The N-player engine reproduced them bit for bit; the optimal-control step solved from the
tabulated linear problem (`mirror_avatar.dynamics.solve_interval`) converges to the same
solutions within its tolerance, so the sessions now stay within `TOLERANCES` of them, while the
Python step loop, the compiled loop and the batch engine still agree bit for bit. The times and
references, which no solver sets, are compared to the rounding another machine may give
(`snapshots`).
"""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.dynamics import FOLLOWER, JOINT, LEADER
from mirror_avatar.engine.batch import play_compiled, run_sessions
from mirror_avatar.engine.loop import play
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.players import RecordedPlayer, VirtualTrainer
from mirror_avatar.sessions.session import Session
from mirror_avatar.training.imitation import train_cyber_player
from snapshots import ATOL, LAST_DIGIT, RTOL, assert_close, perturb_file, read_snapshot

FIXTURES = Path(__file__).parents[1] / "fixtures" / "engine_before"
CHANNELS = ("positions", "velocities", "controls", "references")
DURATION = 10.0
TOLERANCES = {
    "positions": (0.0, 1e-4),
    "velocities": (0.0, 1e-3),
    "controls": (5e-3, 0.05),
    "references": (RTOL, ATOL),
}
"""Largest relative and absolute difference from the recorded sessions per channel (units,
units/s, units/s²): the step's Newton tolerance is 1e-3 on the control; the references are
drawn as before, to rounding."""


@pytest.fixture(scope="module")
def generators() -> tuple[IMSGenerator, IMSGenerator]:
    return IMSGenerator.load(FIXTURES / "fast32.npz"), IMSGenerator.load(FIXTURES / "slow32.npz")


@pytest.fixture(scope="module")
def trials() -> list:
    return [t.resampled(100.0) for t in load_zhai2017()]


def recording(session: Session) -> dict[str, np.ndarray]:
    """A session's arrays as a fixture's ``.npz`` holds them."""
    return {name: getattr(session, name) for name in ("times", *CHANNELS)}


def assert_recorded(found: dict[str, np.ndarray], recorded: dict[str, np.ndarray]) -> None:
    """Assert that the arrays ``found`` are those ``recorded`` (a fixture's ``.npz``): each
    channel within its `TOLERANCES`, anything else (times, seeds) to rounding."""
    assert found.keys() == recorded.keys()
    for name, expected in recorded.items():
        if name in TOLERANCES:
            rtol, atol = TOLERANCES[name]
            np.testing.assert_allclose(found[name], expected, rtol=rtol, atol=atol, err_msg=name)
        else:
            assert_close(found[name], expected, name)


def assert_identical(first: Session, second: Session) -> None:
    for channel in CHANNELS:
        np.testing.assert_array_equal(getattr(first, channel), getattr(second, channel))


def lineups(generators, trials) -> dict[str, tuple[list, int]]:
    fast, slow = generators
    return {
        "vt_leader_vt_follower": (
            [VirtualTrainer(LEADER, slow), VirtualTrainer(FOLLOWER, fast)],
            7,
        ),
        "recorded_vt_follower": ([RecordedPlayer(trials[4]), VirtualTrainer(FOLLOWER, slow)], 3),
        "joint_trial_reference": (
            [VirtualTrainer(JOINT, trials[13]), VirtualTrainer(JOINT, fast)],
            5,
        ),
    }


@pytest.mark.parametrize(
    "name", ["vt_leader_vt_follower", "recorded_vt_follower", "joint_trial_reference"]
)
def test_sessions_are_bit_identical_in_both_loops(generators, trials, name) -> None:
    players, seed = lineups(generators, trials)[name]
    looped = play(players, DURATION, seed)
    assert_recorded(recording(looped), read_snapshot(FIXTURES / f"{name}.npz"))
    assert_identical(looped, play_compiled(players, 334, seed))


def test_batch_run_stays_close(generators, trials) -> None:
    fast, slow = generators
    pairs = [
        (VirtualTrainer(LEADER, fast), VirtualTrainer(FOLLOWER, slow)),
        (VirtualTrainer(LEADER, trials[4]), VirtualTrainer(FOLLOWER, fast)),
    ]
    chunks = list(run_sessions(pairs, 4, duration=5.0, seed=11, n_jobs=1, chunk_size=3))
    sessions = [s for chunk in chunks for s in chunk]
    found = {channel: np.stack([getattr(s, channel) for s in sessions]) for channel in CHANNELS}
    found["seeds"] = np.array([s.metadata["seed"] for s in sessions], dtype=np.uint64)
    assert_recorded(found, read_snapshot(FIXTURES / "batch.npz"))


@pytest.mark.parametrize(
    "name", ["vt_leader_vt_follower", "recorded_vt_follower", "joint_trial_reference", "batch"]
)
def test_the_comparison_allows_rounding_and_catches_a_change(name, tmp_path) -> None:
    """The recorded arrays moved by their last digit pass; moved by relative 1e-6 they fail
    (through the times and references: the solved channels' tolerances are wider)."""
    recorded = read_snapshot(FIXTURES / f"{name}.npz")
    rounded, changed = tmp_path / "rounded.npz", tmp_path / "changed.npz"
    for copy, factor in ((rounded, LAST_DIGIT), (changed, 1.0 + 1e-6)):
        shutil.copy(FIXTURES / f"{name}.npz", copy)
        perturb_file(copy, factor)
    assert not np.array_equal(read_snapshot(rounded)["references"], recorded["references"])
    assert_recorded(recorded, read_snapshot(rounded))
    with pytest.raises(AssertionError):
        assert_recorded(recorded, read_snapshot(changed))


@pytest.mark.parametrize(("role", "partner_params"), [("follower", LEADER), ("leader", FOLLOWER)])
def test_training_learns_as_before(generators, role, partner_params) -> None:
    """Q-learning on sessions within the step's tolerance of the recorded ones: the learning
    curve's mean over the last half is within 10 % of the recorded one (which cells a session
    visits, and so the Q-table, may differ); the trained player's closed-loop session is played
    identically by both loops."""
    fast, slow = generators
    expected = json.loads((FIXTURES / "training.json").read_text())[role]
    player, curve = train_cyber_player(
        slow, [fast, slow], role=role, n_sessions=40, seed=0, duration=DURATION, n_jobs=1
    )
    recorded = np.mean(expected["learning_curve_rms"][20:])
    assert np.mean(curve.rms[20:]) == pytest.approx(recorded, rel=0.1)
    partner = VirtualTrainer(partner_params, fast)
    players = [partner, player] if role == "follower" else [player, partner]
    cyber = players.index(player)
    looped = play(players, DURATION, 9)
    assert_identical(looped, play_compiled(players, 334, 9))
    assert np.all(np.isfinite(looped.controls[cyber, :-1]))
    assert set(np.unique(looped.controls[cyber, :-1])) <= set(player.actions_)
