"""Under a file-size limit (``ulimit -f``), a lab export, the lab server and a trial on the clock
fail naming the file they could not write, not the system's bare "File too large"."""

from __future__ import annotations

import json
import resource
import subprocess
import sys

import httpx
import pytest
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
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
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


TRIAL = """
import asyncio, json, math, resource, sys, time
from pathlib import Path
from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.running.trial import LabTrial
from mirror_avatar.realtime.clock import ClockLimits, run_on_clock
from mirror_avatar.realtime.inputs import BrowserInput
players = [{"label": "P1", "kind": "human"}, {"label": "P2", "kind": "human"}]
plan = parse_plan({"condition": "joint", "duration": 20.0, "players": players})
inputs = {k: BrowserInput() for k in plan.humans}
lab = {"session_id": "S", "condition": "joint"}
trial = LabTrial(plan, 1, Path(sys.argv[1]), inputs, {}, time.monotonic, lab)
resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[2]),) * 2)
def move():
    for i, source in inputs.items():
        source.put(0.3 * math.sin(0.05 * trial.k + i), trial.k)
complete, reason = asyncio.run(run_on_clock(trial, ClockLimits(), after_tick=move))
print(json.dumps(trial.finish(complete, reason)))
"""
"""A lab trial played on the clock, its files limited to ``argv[2]`` bytes once it is opened;
prints the trial's summary."""


@pytest.mark.long
def test_a_trial_on_the_clock_under_a_file_size_limit_names_the_file(tmp_path):
    played = subprocess.run([sys.executable, "-c", TRIAL, str(tmp_path), "16384"], text=True,
                            capture_output=True, timeout=300, check=True)  # fmt: skip
    summary = json.loads(played.stdout)
    recording = tmp_path / "trial-01_session.csv"
    assert summary["end_reason"] == f"disk full: cannot write {recording} (File too large)"
    sidecar = json.loads(recording.with_suffix(".json").read_text())
    assert sidecar["metadata"]["end_reason"] == summary["end_reason"]
    assert sidecar["n_samples"] == summary["n_samples"] > 100
    assert not sidecar["metadata"]["complete"]
