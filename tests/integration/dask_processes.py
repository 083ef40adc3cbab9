"""A Dask scheduler and workers started as separate processes on loopback, as docs/cluster.md does.

The guide's rehearsal (``dask scheduler``, ``dask worker``) in plain ``tcp://``, or with TLS
(``--protocol tls`` and the ``--tls-*`` options) when given credentials: one CA file and one
certificate and key that every process, and the client, shows.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from waiting import wait_for

DASK = Path(sys.executable).with_name("dask")
SOURCE = Path(__file__).parents[2] / "src"


@dataclass(frozen=True)
class Credentials:
    """A CA's certificate file and a certificate and key it signed (PEM files)."""

    ca_file: Path
    cert: Path
    key: Path

    def options(self) -> list[str]:
        """The ``--tls-*`` options of ``dask scheduler`` and ``dask worker``."""
        return ["--tls-ca-file", str(self.ca_file), "--tls-cert", str(self.cert),
                "--tls-key", str(self.key)]  # fmt: skip

    def environment(self) -> dict[str, str]:
        """The client's credentials as the guide gives them: Dask's environment variables."""
        return {
            "DASK_DISTRIBUTED__COMM__TLS__CA_FILE": str(self.ca_file),
            "DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT": str(self.cert),
            "DASK_DISTRIBUTED__COMM__TLS__CLIENT__KEY": str(self.key),
        }

    def security(self) -> Any:
        """The same credentials as a `distributed.Security` for a client in this process."""
        from distributed import Security

        return Security(tls_ca_file=str(self.ca_file), tls_client_cert=str(self.cert),
                        tls_client_key=str(self.key), require_encryption=True)  # fmt: skip


@dataclass(frozen=True)
class Cluster:
    """A loopback rehearsal's scheduler address and its processes' ids."""

    address: str
    pids: list[int]


def environment(cache: Path) -> dict[str, str]:
    """The processes' environment: this tree's package first, a private numba cache."""
    path = os.pathsep.join(filter(None, [str(SOURCE), os.environ.get("PYTHONPATH")]))
    return os.environ | {"PYTHONPATH": path, "XDG_CACHE_HOME": str(cache)}


@contextmanager
def loopback_cluster(
    folder: Path, workers: int, credentials: Credentials | None = None
) -> Iterator[Cluster]:
    """Start ``dask scheduler`` and ``workers`` ``dask worker`` processes on loopback.

    With ``credentials`` they speak TLS only, each showing the same certificate; the cluster is
    shut down on leaving, and every process waited for.
    """
    from distributed import Client

    address_file = folder / "scheduler.json"
    tls = [] if credentials is None else credentials.options()
    protocol = [] if credentials is None else ["--protocol", "tls"]
    common = {"env": environment(folder / "cache"), "stdout": subprocess.DEVNULL,
              "stderr": subprocess.DEVNULL}  # fmt: skip
    processes = [
        subprocess.Popen(
            [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", *protocol, *tls,
             "--dashboard-address", "127.0.0.1:0", "--scheduler-file", str(address_file)],
            **common,
        )
    ]  # fmt: skip
    try:
        wait_for(address_file.is_file, 60.0, "the scheduler to start", interval=0.2)
        for _ in range(workers):
            processes.append(
                subprocess.Popen(
                    [str(DASK), "worker", "--scheduler-file", str(address_file), *tls,
                     "--host", "127.0.0.1", "--nthreads", "1",
                     "--dashboard-address", "127.0.0.1:0"],
                    **common,
                )
            )  # fmt: skip
        security = None if credentials is None else credentials.security()
        with Client(scheduler_file=str(address_file), security=security, timeout=60) as client:
            client.wait_for_workers(workers, timeout=120)
            yield Cluster(client.scheduler.address, [p.pid for p in processes])
            client.shutdown()  # the scheduler and workers end at once (a SIGTERM takes seconds)
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in processes:
            process.wait(30)
