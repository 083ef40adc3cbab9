"""The batch engine on a real local Dask cluster gives the same sessions as local processes."""

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import FOLLOWER, LEADER
from mirror_avatar.engine import batch
from mirror_avatar.engine.batch import run_sessions
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.players import VirtualTrainer

distributed = pytest.importorskip("distributed")


@pytest.mark.long
def test_dask_and_local_runs_are_identical(zhai_trials_100hz: list) -> None:
    model = IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[9:12])
    pairs = [(VirtualTrainer(LEADER, model), VirtualTrainer(FOLLOWER, model))]
    local = list(run_sessions(pairs, 5, duration=3.0, seed=4, n_jobs=1, chunk_size=2))
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        remote = list(
            run_sessions(
                pairs,
                5,
                duration=3.0,
                seed=4,
                scheduler=cluster.scheduler_address,
                chunk_size=2,
            )
        )
    assert [[s.metadata["session"] for s in chunk] for chunk in remote] == [[0, 1], [2, 3], [4]]
    for a, b in zip(sum(local, []), sum(remote, []), strict=True):
        np.testing.assert_array_equal(a.positions, b.positions)
        np.testing.assert_array_equal(a.controls, b.controls)


def test_unreachable_scheduler_is_one_line(zhai_trials_100hz: list, monkeypatch) -> None:
    monkeypatch.setattr(batch, "DASK_CONNECT_TIMEOUT", 1.0)
    model = IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[9:12])
    pairs = [(VirtualTrainer(LEADER, model), VirtualTrainer(FOLLOWER, model))]
    with pytest.raises(InputError, match="cannot reach"):
        next(run_sessions(pairs, 1, scheduler="tcp://127.0.0.1:1"))
