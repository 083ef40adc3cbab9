"""The multi-machine guide (docs/cluster.md) followed on one machine, over loopback.

A scheduler and two workers are started as separate processes with the guide's commands
(``dask scheduler``, ``dask worker``); ``avatar create --scheduler`` then builds the same avatar
file as the local run: every array and every metadata value but the build timings.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import psutil
import pytest
from dask_processes import Cluster, loopback_cluster

from mirror_avatar.cli import main
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.engine import batch
from mirror_avatar.files.model_files import load_model
from mirror_avatar.files.trial_io import write_csv_trial
from mirror_avatar.motion.generator import IMSGenerator

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    """Start ``dask scheduler`` and two ``dask worker`` processes on loopback, as the guide's
    rehearsal does."""
    with loopback_cluster(tmp_path_factory.mktemp("cluster"), workers=2) as started:
        yield started


def _without_timings(value: Any) -> Any:
    """Drop every key that holds a duration (its name says seconds)."""
    if isinstance(value, dict):
        return {k: _without_timings(v) for k, v in value.items() if "seconds" not in k}
    if isinstance(value, list):
        return [_without_timings(v) for v in value]
    return value


def test_the_rehearsal_listens_on_loopback_only(cluster: Cluster) -> None:
    listening = [
        (pid, connection.laddr)
        for pid in cluster.pids
        for connection in psutil.Process(pid).net_connections(kind="inet")
        if connection.status == psutil.CONN_LISTEN
    ]
    assert len({pid for pid, _ in listening}) == 3, listening
    assert all(address.ip == "127.0.0.1" for _, address in listening), listening


def test_an_unreachable_scheduler_is_refused_before_the_trials_are_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(batch, "DASK_CONNECT_TIMEOUT", 1.0)
    missing = tmp_path / "no-such-trials"
    command = ["avatar", "create", str(missing), "--name", "P01",
               "--scheduler", "tcp://127.0.0.1:1", "--out", str(tmp_path / "P01.npz")]  # fmt: skip
    assert main(command) == 2
    error = capsys.readouterr().err
    assert "cannot reach the Dask scheduler" in error and "no-such-trials" not in error
    assert list(tmp_path.iterdir()) == []


@pytest.mark.long
def test_avatar_create_on_the_cluster_gives_the_local_file(
    cluster: Cluster, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    source = IMSGenerator(n_symbols=64, random_state=7).fit(load_zhai2017()[9:13])
    (tmp_path / "trials").mkdir()
    for k, trial in enumerate(source.sample(30.0, 3, random_state=11)):
        write_csv_trial(trial, tmp_path / "trials" / f"trial{k}.csv")
    fast, slow = tmp_path / "fast.npz", tmp_path / "slow.npz"
    IMSGenerator(n_symbols=32, random_state=0).fit(load_zhai2017()[:3]).save(fast)
    IMSGenerator(n_symbols=32, random_state=0).fit(load_zhai2017()[15:18]).save(slow)
    command = ["avatar", "create", str(tmp_path / "trials"), "--name", "P01",
               "--partners", f"{fast},{slow}", "--sessions", "6", "--jobs", "1",
               "--holdout", "1"]  # fmt: skip
    local, remote = tmp_path / "local.npz", tmp_path / "remote.npz"
    assert main([*command, "--out", str(local)]) == 0
    assert main([*command, "--scheduler", cluster.address, "--out", str(remote)]) == 0
    local_arrays, local_metadata = load_model(local, "mirror-avatar/avatar", 1, ())
    remote_arrays, remote_metadata = load_model(remote, "mirror-avatar/avatar", 1, ())
    assert local_arrays.keys() == remote_arrays.keys()
    for name, array in local_arrays.items():
        np.testing.assert_array_equal(remote_arrays[name], array, err_msg=name)
    assert _without_timings(remote_metadata) == _without_timings(local_metadata)
