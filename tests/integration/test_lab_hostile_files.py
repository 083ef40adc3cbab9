"""The real lab server given hostile files and bodies: a participant's run resumed from a FIFO, a
huge or a deeply nested ``study.json``, deeply nested JSON and TOML, each refused in one line
while the server goes on answering; and the researcher's token keeping its rate in a flood."""

from __future__ import annotations

import asyncio
import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from test_lab_server import BEARER, TOKEN
from test_lab_study import PROTOCOL

from mirror_avatar.cli import main
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread

DEADLINE = 60.0
"""Seconds any request of these tests may take before the test fails (a frozen server)."""

TOO_DEEP = "is TOML nested deeper than the limit of 32 levels"
DEEP_TOML = "x = " + "[" * 60_000 + "]" * 60_000 + "\n"
DOTTED_TOML = PROTOCOL.replace('label = "P1"', "label = {" + ".".join(["k"] * 3000) + " = 1}", 1)
"""The study protocol with a player's label a table nested by dotted keys (``{k.k.k = 1}``)."""


@pytest.fixture
def out(tmp_path: Path) -> Path:
    return tmp_path / "out"


@pytest.fixture
def lab(tmp_path: Path, out: Path) -> Iterator[ServerThread]:
    path = tmp_path / "study.toml"
    path.write_text(PROTOCOL)
    settings = LabSettings(out_dir=out, token=TOKEN, countdown=1, protocol=load_protocol(path),
                           requests_per_second=2.0)  # fmt: skip
    with ServerThread(create_lab_app(settings)) as running:
        yield running


def schedule_of(out: Path, participant: int) -> Path:
    folder = out / f"study-p{participant:03d}"
    folder.mkdir(parents=True)
    return folder / "study.json"


def release(fifo: Path) -> None:
    """Open a FIFO for writing and close it: a reader waiting on it gets its end of file."""
    with contextlib.suppress(OSError):
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))


def test_the_server_answers_while_a_fifo_study_json_is_refused(lab, out):
    fifo = schedule_of(out, 7)
    os.mkfifo(fifo)

    async def scenario() -> tuple[httpx.Response, httpx.Response]:
        async with httpx.AsyncClient(base_url=lab.url, headers=BEARER, timeout=DEADLINE) as api:
            resume = asyncio.create_task(api.post("/api/sessions", json={"participant": 7}))
            listing = await api.get("/api/sessions")
            return await resume, listing

    try:
        resumed, listed = asyncio.run(scenario())
    finally:
        release(fifo)
    assert listed.status_code == 200 and listed.json()["sessions"] == []
    assert resumed.status_code == 400
    error = resumed.json()["error"]
    assert error.startswith(f"{fifo}: this folder holds no readable study (is a named pipe")
    assert "\n" not in error


def test_a_huge_or_deeply_nested_study_json_is_refused_in_one_line(lab, out):
    with schedule_of(out, 8).open("wb") as file:
        file.truncate(600 * 2**20)  # sparse: its size is real, its blocks are not
    schedule_of(out, 9).write_text("[" * 200_000 + "]" * 200_000)
    for participant, problem in ((8, "over the limit of"), (9, "nested deeper than the limit")):
        answer = httpx.post(f"{lab.url}/api/sessions", json={"participant": participant},
                            headers=BEARER, timeout=DEADLINE)  # fmt: skip
        assert answer.status_code == 400, answer.text
        assert problem in answer.json()["error"] and "\n" not in answer.json()["error"]
    created = httpx.post(f"{lab.url}/api/sessions", json={"participant": 1}, headers=BEARER)
    assert created.status_code == 201, created.text


def test_deeply_nested_bodies_and_protocols_are_refused_in_one_line(lab, tmp_path, capsys):
    deep = httpx.post(f"{lab.url}/api/sessions", content=b"[" * 30_000, headers=BEARER
                      | {"Content-Type": "application/json"}, timeout=DEADLINE)  # fmt: skip
    assert deep.status_code == 400
    assert deep.json()["error"].startswith("the request body is JSON nested deeper than the limit")
    for text in (DOTTED_TOML, DEEP_TOML):
        body = {"name": "deep.toml", "text": text}
        loaded = httpx.post(f"{lab.url}/api/protocol", json=body, headers=BEARER,
                            timeout=DEADLINE)  # fmt: skip
        assert loaded.status_code == 400
        assert loaded.json() == {"error": f"deep.toml: {TOO_DEEP}"}
    path = tmp_path / "deep.toml"
    path.write_text(DEEP_TOML)
    assert main(["lab", "--protocol", str(path), "--out", str(tmp_path / "cli")]) == 2
    assert capsys.readouterr().err.strip().endswith(f"{path}: {TOO_DEEP}")


def test_the_researchers_token_keeps_its_rate_while_its_address_floods(lab):
    with httpx.Client(base_url=lab.url, timeout=DEADLINE) as anonymous:
        for _ in range(200):
            if anonymous.get("/api/sessions").status_code == 429:
                break
        else:
            pytest.fail("the anonymous requests were never limited")
        assert anonymous.get("/api/sessions").status_code == 429
        assert anonymous.get("/api/sessions", headers=BEARER).status_code == 200
