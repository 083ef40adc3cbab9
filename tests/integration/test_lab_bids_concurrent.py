"""Exports into one BIDS dataset at the same time - threads of one process, processes, and the
real lab server's export requests - take turns: every subject on disk is in participants.tsv."""

from __future__ import annotations

import math
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest
from test_lab_server import BEARER, TOKEN

from mirror_avatar.files.bids.tables import read_tsv
from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.export.bids import export_bids
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.lab.running.trial import LabTrial
from mirror_avatar.realtime.inputs import BrowserInput
from mirror_avatar.testing import ServerThread

TRIES = 3
"""Datasets each test exports its sessions into, at once (before the lock, rows were lost)."""

CLI = "from mirror_avatar.console import run; run()"
"""The command line, run in a process of its own."""


def dyad(prefix: str, trials: int = 2) -> dict[str, object]:
    players = [{"label": f"{prefix}{k}", "kind": "human"} for k in (1, 2)]
    return {"condition": "joint", "duration": 4.0, "trials": trials, "players": players}


def record(folder: Path, plan_data: dict[str, object]) -> Path:
    """Record every trial of a plan into a lab session folder, as the server writes them."""
    plan = parse_plan(plan_data)
    folder.mkdir(parents=True, exist_ok=True)
    for n in range(1, plan.trials + 1):
        inputs = {k: BrowserInput() for k in plan.humans}
        lab = {"session_id": folder.name, "condition": plan.condition}
        trial = LabTrial(plan, n, folder, inputs, {}, time.monotonic, lab)
        while not trial.finished:
            for i, source in inputs.items():
                source.put(0.3 * math.sin(0.05 * trial.k + i + n), trial.k)
            trial.tick()
        trial.finish(True, "completed")
    return folder


def subjects_missing(bids: Path) -> set[str]:
    """The subjects with a folder in the dataset but no row in its participants.tsv."""
    _, rows = read_tsv(bids / "participants.tsv", "participant_id")
    on_disk = {path.name for path in bids.glob("sub-*") if path.is_dir()}
    return on_disk - set(rows)


def test_exports_from_threads_into_one_dataset_keep_every_subject(tmp_path):
    sessions = [record(tmp_path / f"20261127T0000{k}0-00{k}", dyad(p))
                for k, p in enumerate("ABC")]  # fmt: skip
    for attempt in range(TRIES):
        bids = tmp_path / f"bids-{attempt}"
        start = threading.Barrier(len(sessions))

        def export(session: Path, bids: Path = bids, start: threading.Barrier = start) -> None:
            start.wait()
            export_bids(session, bids)

        threads = [threading.Thread(target=export, args=(s,)) for s in sessions]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(120)
        assert len(list(bids.glob("sub-*"))) == 6
        assert subjects_missing(bids) == set()


@pytest.mark.long
def test_exports_from_processes_into_one_dataset_keep_every_subject(tmp_path):
    sessions = [record(tmp_path / f"20261127T0100{k}0-00{k}", dyad(p, trials=12))
                for k, p in enumerate("DE")]  # fmt: skip
    command = [
        sys.executable,
        "-c",
        "from mirror_avatar.console import run; run()",
        "lab",
        "export",
    ]
    for attempt in range(TRIES):
        bids = tmp_path / f"bids-{attempt}"
        exports = [subprocess.Popen([*command, str(s), "--out", str(bids)]) for s in sessions]
        assert [export.wait(300) for export in exports] == [0, 0]
        assert len(list(bids.glob("sub-*"))) == 4
        assert subjects_missing(bids) == set()


def test_the_servers_exports_into_one_folder_keep_every_subject(tmp_path):
    out = tmp_path / "out"
    settings = LabSettings(out_dir=out, token=TOKEN, countdown=1)

    def export_both(url: str, ids: list[str], folder: str) -> list[httpx.Response]:
        """Ask for every session's export into ``folder`` at once, one thread and client each."""

        def export(sid: str) -> httpx.Response:
            with httpx.Client(base_url=url, headers=BEARER, timeout=300) as api:
                return api.post(f"/api/sessions/{sid}/export", json={"folder": folder})

        with ThreadPoolExecutor(len(ids)) as pool:
            return list(pool.map(export, ids))

    with ServerThread(create_lab_app(settings)) as lab:
        ids = []
        for prefix in "FG":
            created = httpx.post(f"{lab.url}/api/sessions", json=dyad(prefix), headers=BEARER)
            assert created.status_code == 201, created.text
            ids.append(created.json()["id"])
            record(out / ids[-1], dyad(prefix))
        for attempt in range(TRIES):
            answers = export_both(lab.url, ids, f"shared{attempt}")
            assert [answer.status_code for answer in answers] == [200, 200]
            bids = out / f"shared{attempt}"
            assert len(list(bids.glob("sub-*"))) == 4
            assert subjects_missing(bids) == set()
