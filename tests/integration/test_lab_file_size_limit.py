"""Under a file-size limit (``ulimit -f``), a lab export and the lab server fail in one line
naming the file they could not write, not the system's bare "File too large"."""

from __future__ import annotations

import resource
import subprocess
import sys

import httpx
from test_lab_bids_concurrent import CLI, dyad, record

LIMIT_BYTES = 6 * 1024
"""The file-size limit of the export's process: above its small files, below its motion files."""


def limited() -> None:
    """Limit the files this process writes to `LIMIT_BYTES` (SIGXFSZ is ignored by Python)."""
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, LIMIT_BYTES))


def test_an_export_under_a_file_size_limit_names_the_file(tmp_path):
    session = record(tmp_path / "20261127T020000-001", dyad("H", trials=1))
    bids = tmp_path / "bids"
    export = subprocess.run(
        [sys.executable, "-c", CLI, "lab", "export", str(session), "--out", str(bids)],
        capture_output=True, text=True, timeout=300, preexec_fn=limited, check=False,
    )  # fmt: skip
    assert export.returncode == 2, export.stderr
    (line,) = export.stderr.splitlines()
    assert line.startswith(f"mirror-avatar: error: {bids}/") and line.endswith(": File too large")


SERVER = """
import resource, sys
from pathlib import Path
from mirror_avatar.lab.server import LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread
settings = LabSettings(out_dir=Path(sys.argv[1]), token="token", countdown=1)
with ServerThread(create_lab_app(settings)) as lab:
    resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[2]),) * 2)
    print(lab.url, flush=True)
    sys.stdin.read()
"""
"""A lab server whose files are limited to ``argv[2]`` bytes once it runs, until stdin closes."""


def test_a_session_the_server_cannot_write_is_refused_naming_the_file(tmp_path):
    out = tmp_path / "out"
    server = subprocess.Popen([sys.executable, "-c", SERVER, str(out), "200"], text=True,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE)  # fmt: skip
    try:
        assert server.stdout is not None
        url = server.stdout.readline().strip()
        answer = httpx.post(f"{url}/api/sessions", json=dyad("W", trials=1), timeout=120,
                            headers={"Authorization": "Bearer token"})  # fmt: skip
    finally:
        server.communicate("", timeout=60)
    assert answer.status_code == 500
    error = answer.json()["error"]
    assert error.startswith(f"{out}/") and error.endswith("/plan.json: File too large")
