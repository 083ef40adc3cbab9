"""The multi-machine guide's TLS cluster (docs/cluster.md) followed on one machine, over loopback.

The test makes its own certificate authority and a certificate and key it signs (with
``cryptography``), starts ``dask scheduler --protocol tls`` and a ``dask worker`` with them, and
runs ``train --scheduler tls://...`` in a fresh process whose credentials are the guide's
environment variables. A client without credentials, a plain ``tcp://`` one and one whose
certificate another authority signed are each refused in one line.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import dask
import pytest
from cryptography import x509
from dask_processes import Cluster, Credentials, environment, loopback_cluster
from tls_servers import certificate, new_key, write_key

from mirror_avatar.cli import main
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.engine.batch import TLS_CREDENTIALS
from mirror_avatar.learning.agent import load_cyber_player
from mirror_avatar.motion.generator import IMSGenerator

distributed = pytest.importorskip("distributed")


def make_credentials(folder: Path) -> Credentials:
    """Write a new self-signed CA and a certificate and key it signed into ``folder``."""
    authority_key, key = new_key(), new_key()
    authority = certificate("mirror-avatar test CA", authority_key, None, authority_key)
    credentials = Credentials(folder / "ca.crt", folder / "cluster.crt", folder / "cluster.key")
    credentials.ca_file.write_bytes(authority)
    issuer = x509.load_pem_x509_certificate(authority)
    credentials.cert.write_bytes(certificate("cluster", key, issuer, authority_key))
    write_key(key, credentials.key)
    return credentials


@pytest.fixture(scope="module")
def credentials(tmp_path_factory: pytest.TempPathFactory) -> Credentials:
    return make_credentials(tmp_path_factory.mktemp("credentials"))


@pytest.fixture(scope="module")
def cluster(
    tmp_path_factory: pytest.TempPathFactory, credentials: Credentials
) -> Iterator[Cluster]:
    """A TLS scheduler and one worker on loopback, both showing the test's certificate."""
    folder = tmp_path_factory.mktemp("cluster")
    with loopback_cluster(folder, workers=1, credentials=credentials) as started:
        yield started


def _chunks_played(cluster: Cluster, credentials: Credentials) -> int:
    """How many chunks of sessions (`mirror_avatar.engine.batch.run_chunk`) the cluster ran."""

    def count(dask_scheduler: distributed.Scheduler) -> int:
        prefix = dask_scheduler.task_prefixes.get("run_chunk")
        return 0 if prefix is None else len(prefix.all_durations)

    security = credentials.security()
    with distributed.Client(cluster.address, security=security, timeout=60) as client:
        return int(client.run_on_scheduler(count))


@pytest.mark.long
def test_train_on_the_tls_cluster_with_the_guides_credentials(
    cluster: Cluster, credentials: Credentials, tmp_path: Path
) -> None:
    assert cluster.address.startswith("tls://127.0.0.1:")
    fast, slow = tmp_path / "fast.npz", tmp_path / "slow.npz"
    IMSGenerator(n_symbols=32, random_state=0).fit(load_zhai2017()[:3]).save(fast)
    IMSGenerator(n_symbols=32, random_state=0).fit(load_zhai2017()[15:18]).save(slow)
    out = tmp_path / "follower.npz"
    result = subprocess.run(
        [sys.executable, "-c", "from mirror_avatar.console import run; run()", "train",
         "--target", str(slow), "--partners", str(fast), "--sessions", "2", "--duration", "5",
         "--scheduler", cluster.address, "--out", str(out)],
        env=environment(tmp_path / "cache") | credentials.environment(),
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    load_cyber_player(out)  # a policy the package reads back
    assert _chunks_played(cluster, credentials) > 0


def _refused(tmp_path: Path, scheduler: str, capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``train --scheduler`` in this process; return its one error line (exit code 2)."""
    command = ["train", "--target", "bundled:slow", "--partners", "bundled:fast",
               "--sessions", "2", "--scheduler", scheduler,
               "--out", str(tmp_path / "follower.npz")]  # fmt: skip
    assert main(command) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1, error
    assert list(tmp_path.iterdir()) == []
    return error


def test_a_client_without_credentials_is_refused_in_one_line(
    cluster: Cluster, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    error = _refused(tmp_path, cluster.address, capsys)
    assert all(variable in error for variable in TLS_CREDENTIALS), error


def test_a_plain_client_is_refused_by_the_tls_scheduler(
    cluster: Cluster, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plain = cluster.address.replace("tls://", "tcp://")
    assert "cannot reach the Dask scheduler" in _refused(tmp_path, plain, capsys)


def test_a_certificate_another_authority_signed_is_refused(
    cluster: Cluster, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    stranger = make_credentials(tmp_path)
    keys = {"ca-file": stranger.ca_file, "client.cert": stranger.cert, "client.key": stranger.key}
    settings = {f"distributed.comm.tls.{key}": str(path) for key, path in keys.items()}
    (tmp_path / "out").mkdir()
    with dask.config.set(settings):
        error = _refused(tmp_path / "out", cluster.address, capsys)
    assert "cannot reach the Dask scheduler" in error and "TLS" in error, error
