"""Seeded lab and study sessions recorded through the real server, as text to compare.

`record` runs, on a real lab server with pages as WebSocket clients, a lab session (a ring of
two people and two avatars) and participant 4's run of the example protocol
(``examples/protocol.toml``: solo, perturbation, questions, whole and timed occlusion, delay),
its durations shortened. The people's pages send no position (a person stays at the centre), so
everything but the clock's timing is seeded: the recordings, the frames each page was sent (the
partners delayed and hidden), its welcomes, questions and end messages. What depends on the
clock's timing (timestamps, input ages, lateness, dates, when an input was judged lost) is
masked, and the metrics and measures are left to their own tests.

Run as a script (``PYTHONPATH=src:tests:tests/integration python
tests/integration/lab_recordings.py``), it writes what it recorded to
``tests/fixtures/lab_recordings/recorded.json``, which ``test_lab_recordings.py`` compares with a
new recording: refresh it (with the code it should pin) only when a change of the recordings is
meant.
"""

from __future__ import annotations

import asyncio
import csv
import io
import json
import re
import sys
from pathlib import Path
from typing import Any

import httpx
from test_lab_server import BEARER, TOKEN, Page, status, welcomed
from test_lab_study import AnsweringPage

from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread
from waiting import wait_for

ROOT = Path(__file__).parents[2]
RECORDED = ROOT / "tests" / "fixtures" / "lab_recordings" / "recorded.json"
"""The recordings pinned, as `record` returns them."""

SHORTENED = (
    ("duration = 30", "duration = 2"),
    ("duration = 45", "duration = 2"),
    ("trials = 2", "trials = 1"),
    ("pause = 5", "pause = 0.5"),
    ("at = 20.0", "at = 1.0"),
    ("occlude = [[10, 15]]", "occlude = [[0.5, 1.2]]"),
)
"""The example protocol's trials shortened: every condition kind, in seconds."""

RING = {
    "condition": "group",
    "graph": "ring",
    "duration": 2.0,
    "pause": 0.5,
    "max_lateness": 10.0,
    "seed": 7,
    "trials": 2,
    "players": [
        {"label": "P1", "kind": "human"},
        {"label": "A1", "kind": "avatar", "spec": "bundled:slow"},
        {"label": "P2", "kind": "human"},
        {"label": "A2", "kind": "avatar", "spec": "bundled:fast"},
    ],
}
"""The lab session recorded: two people and two avatars in a ring, two trials."""

PARTICIPANT = 4
"""The participant recorded: their partner in 'lead' (delay, timed occlusion) is an avatar."""

TIMING_COLUMNS = re.compile(r"time|clock_s|(age_ms|alive)_.*|late_ms|step_ms")
"""Columns of a recording's CSV files that depend on the clock's timing."""

TIMING_KEYS = {
    "created_utc", "started_utc", "ended_utc", "utc", "clock", "tick_lateness_ms", "max_lateness",
    "held", "lost", "metrics", "measures", "source",
}  # fmt: skip
"""Keys of the JSON files and messages whose values depend on timing or on the scratch folder
(``source``: the protocol's path), or are tested elsewhere (metrics, measures)."""


class SilentPage(Page):
    """A participant's page that sends no position: it answers pings and keeps every message."""

    async def _send(self, socket: Any) -> None:
        return


class SilentAnsweringPage(SilentPage, AnsweringPage):
    """A silent page that answers every question (first out of range, then properly)."""


def masked(value: Any) -> Any:
    """Return a JSON value with the timing keys' values replaced by ``"*"``."""
    if isinstance(value, dict):
        if "event" in value and "sample" in value:  # an input lost or live again
            value = value | {"sample": "*"}
        out = {k: "*" if k in TIMING_KEYS else masked(v) for k, v in value.items()}
        if isinstance(out.get("input_events"), list):  # pages' events arrive in either order
            out["input_events"] = sorted(out["input_events"], key=lambda e: str(e.get("label")))
        return out
    if isinstance(value, list):
        return [masked(v) for v in value]
    return value


def masked_csv(text: str) -> list[list[str]]:
    """Return a CSV's header and rows, the timing columns' values replaced by ``"*"``."""
    header, *rows = csv.reader(io.StringIO(text))
    timing = [TIMING_COLUMNS.fullmatch(name) is not None for name in header]
    return [header] + [["*" if t else v for t, v in zip(timing, row, strict=True)] for row in rows]


def folder_files(folder: Path) -> dict[str, Any]:
    """Return every file of a session's folder, masked, by name (the session's id masked too)."""
    files: dict[str, Any] = {}
    for path in sorted(folder.iterdir()):
        text = path.read_text().replace(folder.name, "SESSION")
        files[path.name] = masked(json.loads(text)) if path.suffix == ".json" else masked_csv(text)
    return files


def page_record(page: Page) -> dict[str, Any]:
    """Return what a page was sent, frames by sample and trial, the rest in order."""
    frames: dict[str, list[Any]] = {}
    trial = 0
    others = []
    for message in page.messages:
        kind = message["type"]
        if kind == "go":
            trial = message["trial"]
        if kind == "frame":
            frames[f"{trial}:{message['k']}"] = message["x"]
        elif kind not in ("ping", "countdown"):
            others.append(masked(message))
    return {"frames": frames, "messages": others}


def play(lab: ServerThread, sid: str, pages: list[Page]) -> None:
    """Start a session with its pages joined (forced) and wait until it has finished."""

    async def scenario() -> None:
        tasks = [asyncio.create_task(page.play(300.0)) for page in pages]
        await welcomed(pages)
        started = await asyncio.to_thread(
            httpx.post, f"{lab.url}/api/sessions/{sid}/start", json={"force": True}, headers=BEARER
        )
        assert started.status_code == 200, started.text
        await asyncio.to_thread(
            wait_for, lambda: status(lab, sid)["state"] == "finished", 300.0, f"{sid} to finish"
        )
        await asyncio.gather(*tasks)

    asyncio.run(scenario())


def record(out: Path) -> dict[str, Any]:
    """Record the lab session and the study participant into ``out``; return them, masked."""
    protocol_file = out / "protocol.toml"
    text = (ROOT / "examples" / "protocol.toml").read_text()
    for long, short in SHORTENED:
        assert long in text, long
        text = text.replace(long, short)
    protocol_file.write_text(text)
    settings = LabSettings(
        out_dir=out / "out",
        token=TOKEN,
        countdown=1,
        max_tick=60.0,  # the first step compiles: no trial ends for a slow step
        protocol=load_protocol(protocol_file),
    )
    recorded: dict[str, Any] = {}
    with ServerThread(create_lab_app(settings)) as lab:
        ring = httpx.post(f"{lab.url}/api/sessions", json=RING, headers=BEARER).json()
        pages: list[Page] = [SilentPage(ring["links"]["P1"])]
        play(lab, ring["id"], pages)
        recorded["lab"] = {
            "files": folder_files(settings.out_dir / ring["id"]),
            "pages": [page_record(page) for page in pages],
        }
        study = httpx.post(
            f"{lab.url}/api/sessions", json={"participant": PARTICIPANT}, headers=BEARER
        )
        sid = study.json()["id"]
        pages = [SilentAnsweringPage(link) for link in study.json()["links"].values()]
        play(lab, sid, pages)
        recorded["study"] = {
            "files": folder_files(settings.out_dir / sid),
            "pages": [page_record(page) for page in pages],
        }
    return recorded


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as scratch:
        target = Path(sys.argv[1]) if len(sys.argv) > 1 else RECORDED
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(json.dumps(record(Path(scratch)), sort_keys=True) + "\n")
