"""Tests of the game engine and of session files."""

from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.errors import InputError
from mirror_avatar.game import Session, load_session, play
from mirror_avatar.generator import IMSGenerator
from mirror_avatar.hkb import FOLLOWER, LEADER
from mirror_avatar.metrics import compute_circular_variance, compute_relative_phase
from mirror_avatar.players import RecordedPlayer, VirtualTrainer


@pytest.fixture(scope="module")
def generator(zhai_trials_100hz: list) -> IMSGenerator:
    return IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[9:12])


@pytest.fixture(scope="module")
def session(generator: IMSGenerator) -> Session:
    return play(VirtualTrainer(LEADER, generator), VirtualTrainer(FOLLOWER, generator), 20.0, 7)


def test_session_shapes_and_records(session: Session) -> None:
    assert session.times.size == 668 and session.positions.shape == (2, 668)
    assert session.period == pytest.approx(0.03)
    assert np.all(np.isfinite(session.controls[:, :-1])) and np.all(
        np.isnan(session.controls[:, -1])
    )
    assert np.all(np.abs(session.positions) <= 0.5)
    assert session.metadata["seed"] == 7 and len(session.metadata["player_seeds"]) == 2
    assert session.metadata["players"][0]["params"]["theta_p"] == 0.1


def test_same_seed_same_session(generator: IMSGenerator, session: Session) -> None:
    again = play(VirtualTrainer(LEADER, generator), VirtualTrainer(FOLLOWER, generator), 20.0, 7)
    np.testing.assert_array_equal(again.positions, session.positions)
    other = play(VirtualTrainer(LEADER, generator), VirtualTrainer(FOLLOWER, generator), 20.0, 8)
    assert not np.array_equal(other.positions, session.positions)


def test_follower_lags_the_leader(session: Session) -> None:
    phase = compute_relative_phase(session.positions[0], session.positions[1])
    assert np.angle(np.mean(np.exp(1j * phase))) > 0
    assert compute_circular_variance(phase) > 0.8


def test_velocities_are_consistent_with_positions(session: Session) -> None:
    inner = session.positions[:, 1:-1]
    numeric = (session.positions[:, 2:] - session.positions[:, :-2]) / (2 * session.period)
    moving = np.abs(inner) < 0.49
    assert np.median(np.abs(numeric - session.velocities[:, 1:-1])[moving]) < 0.05


@pytest.mark.parametrize("save", ["save", "save_csv"])
def test_save_and_load_round_trip(session: Session, tmp_path: Path, save: str) -> None:
    path = tmp_path / ("s.parquet" if save == "save" else "s.csv")
    getattr(session, save)(path)
    back = load_session(path)
    for name in ("times", "positions", "velocities", "controls", "references"):
        np.testing.assert_array_equal(getattr(back, name), getattr(session, name))
    assert back.labels == session.labels and back.metadata["seed"] == 7


def test_recorded_player_has_no_control(zhai_trials_100hz, generator) -> None:
    session = play(RecordedPlayer(zhai_trials_100hz[0]), VirtualTrainer(FOLLOWER, generator), 3.0)
    assert np.all(np.isnan(session.controls[0])) and np.all(np.isnan(session.references[0]))
    assert isinstance(session.metadata["seed"], int)


def test_bad_session_files(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text("time,position_0\n0,0\n")
    with pytest.raises(InputError, match="missing column"):
        load_session(tmp_path / "a.csv")
    (tmp_path / "b.parquet").write_bytes(b"junk")
    with pytest.raises(InputError, match="Parquet"):
        load_session(tmp_path / "b.parquet")
    with pytest.raises(InputError, match="no such file"):
        load_session(tmp_path / "c.parquet")


def test_mismatched_periods_are_refused(generator) -> None:
    with pytest.raises(InputError, match="periods differ"):
        play(
            VirtualTrainer(LEADER.with_(period=0.02), generator),
            VirtualTrainer(FOLLOWER, generator),
        )
