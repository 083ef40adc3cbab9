"""Tests of the batch engine: identical to one-at-a-time play, whatever the chunking or backend."""

import numpy as np
import pytest

from mirror_avatar.batch import run_sessions, session_seeds
from mirror_avatar.errors import InputError
from mirror_avatar.game import play
from mirror_avatar.generator import IMSGenerator
from mirror_avatar.hkb import FOLLOWER, LEADER
from mirror_avatar.players import RecordedPlayer, VirtualTrainer


@pytest.fixture(scope="module")
def pairs(zhai_trials_100hz: list) -> list:
    fast = IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[0:3])
    slow = IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[9:12])
    return [
        (VirtualTrainer(LEADER, fast), VirtualTrainer(FOLLOWER, slow)),
        (VirtualTrainer(LEADER, slow), VirtualTrainer(FOLLOWER, slow)),
        (VirtualTrainer(LEADER, zhai_trials_100hz[5]), VirtualTrainer(FOLLOWER, fast)),
    ]


def collect(batches) -> dict[str, np.ndarray]:
    batches = list(batches)
    names = ("positions", "velocities", "controls", "references", "pair_index", "seeds")
    return {name: np.concatenate([getattr(b, name) for b in batches]) for name in names}


def test_batch_sessions_equal_played_sessions(pairs) -> None:
    run = collect(run_sessions(pairs, 6, duration=5.0, seed=11, n_jobs=1, chunk_size=4))
    assert run["positions"].shape == (6, 2, 168)
    np.testing.assert_array_equal(run["seeds"], session_seeds(11, 6))
    for i in range(6):
        session = play(*pairs[i % 3], duration=5.0, seed=int(run["seeds"][i]))
        np.testing.assert_array_equal(run["positions"][i], session.positions)
        np.testing.assert_array_equal(run["velocities"][i], session.velocities)
        np.testing.assert_array_equal(run["controls"][i], session.controls)
        np.testing.assert_array_equal(run["references"][i], session.references)
    assert list(run["pair_index"]) == [0, 1, 2, 0, 1, 2]


def test_chunking_and_processes_do_not_change_results(pairs) -> None:
    inline = collect(run_sessions(pairs, 7, duration=4.0, seed=2, n_jobs=1, chunk_size=7))
    processes = collect(run_sessions(pairs, 7, duration=4.0, seed=2, n_jobs=2, chunk_size=2))
    for name, values in inline.items():
        np.testing.assert_array_equal(values, processes[name])


def test_chunks_stream_in_order(pairs) -> None:
    starts = [b.start for b in run_sessions(pairs, 5, duration=2.0, n_jobs=1, chunk_size=2)]
    assert starts == [0, 2, 4]


def test_bad_runs_are_refused(pairs, zhai_trials_100hz) -> None:
    with pytest.raises(InputError, match="virtual trainers"):
        next(run_sessions([(RecordedPlayer(zhai_trials_100hz[0]), pairs[0][1])], 1))
    with pytest.raises(InputError, match="scheduler"):
        next(run_sessions(pairs, 1, backend="dask"))
    with pytest.raises(InputError, match="unknown backend"):
        next(run_sessions(pairs, 1, backend="spark"))
