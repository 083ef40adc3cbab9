"""A study protocol run through the real lab server: each participant's conditions in their
counterbalanced order, blinded pages, the truth in the files, and a killed server resumed."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from test_lab_server import BEARER, TOKEN, Page, command, status, welcomed

from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.sessions.session import Session
from mirror_avatar.testing import ServerThread
from waiting import wait_for

QUESTIONS = """
[questions.partner]
text = "Was your partner a person or a computer?"
kind = "choice"
options = ["a person", "a computer"]

[questions.confidence]
text = "How confident are you?"
kind = "likert"
points = 7

[questions.remarks]
text = "Anything to add?"
kind = "text"
max_chars = 40
"""
"""A choice, a Likert scale and a free text, asked by the study tests."""

PROTOCOL = f"""
title = "test study"
seed = 7
{QUESTIONS}
[[blocks]]
name = "dyads"
order = "williams"
after_block = ["remarks"]

[[blocks.conditions]]
name = "follow"
game = "leader_follower"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "A1", kind = "avatar", spec = "bundled:slow" }},
]
leaders = ["A1"]
trials = 1
duration = 2
pause = 0.5

[[blocks.conditions]]
name = "together"
game = "joint"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "P2", kind = "person-or-avatar", spec = "bundled:slow" }},
]
trials = 2
duration = 2
pause = 0.5
after_trial = ["partner", "confidence"]
"""


class AnsweringPage(Page):
    """A participant's page that answers every question: first out of range, then properly."""

    ANSWERS: dict[str, Any] = {"partner": "a computer", "confidence": 5, "remarks": "smooth"}  # noqa: RUF012

    async def on_message(self, socket: Any, message: dict[str, Any]) -> None:
        await super().on_message(socket, message)
        if message["type"] == "questions":
            await self._answer(socket, message)

    async def _answer(self, socket: Any, message: dict[str, Any]) -> None:
        for question in message["questions"]:
            answer = {"type": "answer", "trial": message["trial"], "question": question["id"]}
            if question["kind"] == "likert":
                await socket.send(json.dumps(answer | {"value": question["points"] + 1}))
            await socket.send(json.dumps(answer | {"value": self.ANSWERS[question["id"]]}))


@pytest.fixture
def protocol_file(tmp_path: Path) -> Path:
    path = tmp_path / "study.toml"
    path.write_text(PROTOCOL)
    return path


@contextlib.contextmanager
def protocol_lab(protocol_file: Path) -> Iterator[ServerThread]:
    """A lab server running the protocol file, its folders under ``out`` beside it."""
    protocol = load_protocol(protocol_file)
    out = protocol_file.parent / "out"
    settings = LabSettings(out_dir=out, token=TOKEN, countdown=1, protocol=protocol)
    with ServerThread(create_lab_app(settings)) as running:
        yield running


@pytest.fixture
def lab(protocol_file: Path) -> Iterator[ServerThread]:
    with protocol_lab(protocol_file) as running:
        yield running


def create_participant(url: str, participant: int, headers: dict[str, str]) -> dict[str, Any]:
    response = httpx.post(f"{url}/api/sessions", json={"participant": participant}, headers=headers)
    assert response.status_code == 201, response.text
    return response.json()


def play_to_the_end(
    lab: ServerThread,
    sid: str,
    pages: list[Page],
    seconds: float = 40.0,
    force: bool = False,
    seen: set[str] | None = None,
    timeout: float = 120.0,
    judged: bool = False,
) -> None:
    """Start a participant's run with its pages playing and wait until it has finished.

    ``seen`` collects where in the protocol the console said the run was, poll by poll;
    ``timeout`` (s) is the deadline of the wait; with ``judged`` the run is started once the
    server has judged every page's entry (a protocol screening round trips).
    """

    async def scenario() -> None:
        tasks = [asyncio.create_task(page.play(seconds)) for page in pages]
        await welcomed(pages)
        if judged:
            await asyncio.to_thread(wait_for, entries_judged, 60.0, "every entry judged")
        body = {"force": True} if force else {}
        started = await asyncio.to_thread(
            httpx.post, f"{lab.url}/api/sessions/{sid}/start", json=body, headers=BEARER
        )
        assert started.status_code == 200, started.text
        await asyncio.to_thread(wait_for, finished, timeout, f"the run {sid} to finish")
        await asyncio.gather(*tasks)

    def entries_judged() -> bool:
        slots = status(lab, sid)["slots"]
        return all(slot["entry_rtt_p95_ms"] is not None for slot in slots if "joined" in slot)

    def finished() -> bool:
        now = status(lab, sid)
        if seen is not None:
            seen.add(now["study"]["where"])
        return bool(now["state"] == "finished")

    asyncio.run(scenario())


def person_plays_together(protocol_file: Path, participant: int) -> bool:
    steps = load_protocol(protocol_file).schedule(participant)
    return next(step.persons["P2"] for step in steps if step.name == "together")


@pytest.mark.long
@pytest.mark.parametrize("participant", [0, 1])
def test_a_participant_plays_the_protocol_in_their_order_blinded(
    lab, tmp_path, protocol_file, participant
):
    expected = [step.name for step in load_protocol(protocol_file).schedule(participant)]
    created = create_participant(lab.url, participant, BEARER)
    sid = created["id"]
    assert sid == f"study-p{participant:03d}"
    assert set(created["links"]) == {"P1", "P2"}
    assert created["study"]["order"] == expected
    first = "follow" if expected[0] == "follow" else "together"
    assert created["study"]["where"] == f"block 1 of 1, condition '{first}', trial 1 of " + (
        "1" if first == "follow" else "2"
    )
    pages = [
        AnsweringPage(created["links"]["P1"]),
        AnsweringPage(created["links"]["P2"], phase=-0.4),
    ]
    seen: set[str] = set()
    play_to_the_end(lab, sid, pages, force=True, seen=seen)
    assert "block 1 of 1, condition 'together', trial 2 of 2" in seen
    folder = tmp_path / "out" / sid
    study = json.loads((folder / "study.json").read_text())
    assert [c["condition"] for c in study["order"]] == expected
    assert study["seed"] == 7 and study["participant"] == participant
    person = person_plays_together(protocol_file, participant)
    trials = [load_session(folder / f"trial-{n:02d}_session.csv") for n in (1, 2, 3)]
    names = [t.metadata["lab"]["protocol_condition"] for t in trials]
    assert names == [n for n in expected for _ in range(1 if n == "follow" else 2)]
    for trial in trials:
        lab_meta = trial.metadata["lab"]
        assert trial.metadata["complete"]
        if lab_meta["protocol_condition"] == "together":
            assert lab_meta["partners"] == {"P1": "human", "P2": "human" if person else "avatar"}
        else:
            assert lab_meta["partners"] == {"P1": "human", "A1": "avatar"}
    for page in pages:  # blinded: the partner is "your partner", never a label or a kind
        for welcome in page.of_type("welcome"):
            assert [v["label"] for v in welcome["visible"][1:]] in ([], ["your partner"])
            assert "avatar" not in json.dumps(welcome) and "human" not in json.dumps(welcome)
    p2_ends = [e["trial"] for e in pages[1].of_type("end")]
    together = [n for n, name in zip((1, 2, 3), names, strict=True) if name == "together"]
    assert p2_ends == (together if person else [])
    for n in (1, 2, 3):  # questions after each 'together' trial, the block's after the last
        path = folder / f"trial-{n:02d}_answers.json"
        after_trial = ["partner", "confidence"] if n in together else []
        after_block = ["remarks"] if n == 3 else []
        if not after_trial + after_block:
            assert not path.exists()
            continue
        saved = json.loads(path.read_text())
        assert (saved["after_trial"], saved["after_block"]) == (after_trial, after_block)
        players = ["P1", "P2"] if person and n in together else ["P1"]
        assert sorted(saved["answers"]) == players
        for label in players:
            values = {q: a["value"] for q, a in saved["answers"][label].items()}
            assert values == {q: AnsweringPage.ANSWERS[q] for q in after_trial + after_block}
    for end in pages[0].of_type("end"):  # no countdown to a trial that waits for answers
        asked = end["trial"] in together or end["trial"] == 3
        assert end["next_in"] == (None if asked else 0.5)
    refusals = [m["message"] for m in pages[0].of_type("error")]
    assert refusals == ["confidence: choose a point from 1 to 7"] * len(together)
    assert_console_lists_the_trials(status(lab, sid), folder, trials)


def assert_console_lists_the_trials(final: dict[str, Any], folder: Path, trials: list) -> None:
    """The finished run's status: nobody waits, and each trial's row names its condition, its
    partners' true kinds and the answers given after it, as the files record them."""
    assert final["state"] == "finished" and final["study"]["waiting"] == []
    assert [row["n"] for row in final["trials"]] == [1, 2, 3]
    for row, trial in zip(final["trials"], trials, strict=True):
        meta = trial.metadata["lab"]
        assert (row["block"], row["condition"]) == (meta["block"], meta["protocol_condition"])
        assert row["partners"] == meta["partners"]
        path = folder / f"trial-{row['n']:02d}_answers.json"
        saved = json.loads(path.read_text())["answers"] if path.exists() else {}
        given = {label: {q: a["value"] for q, a in qs.items()} for label, qs in saved.items()}
        assert row["answers"] == given


def test_study_requests_are_refused_with_one_line(lab, tmp_path):
    for body, problem in (
        ({"participant": -1}, "participant: must be the participant's number, 0 or more"),
        ({"participant": "one"}, "participant: must be the participant's number, 0 or more"),
        ({"participant": 1000}, "participant: must be at most 999"),
    ):
        answer = httpx.post(f"{lab.url}/api/sessions", json=body, headers=BEARER)
        assert answer.status_code == 400 and answer.json() == {"error": problem}


def test_creating_an_open_participants_run_again_answers_it_as_it_is(lab):
    created = create_participant(lab.url, 0, BEARER)  # a reloaded console creates it again
    again = httpx.post(f"{lab.url}/api/sessions", json={"participant": 0}, headers=BEARER)
    assert again.status_code == 200
    assert (again.json()["id"], again.json()["state"]) == (created["id"], "waiting")
    assert again.json()["links"] == created["links"]  # the same join links, still valid


def test_the_cli_refuses_a_bad_protocol_in_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(PROTOCOL.replace('game = "joint"', 'game = "duet"'))
    result = subprocess.run(
        [Path(sys.executable).parent / "mirror-avatar", "lab", "--protocol", str(bad),
         "--out", str(tmp_path / "out"), "--port", "0", "--no-lsl"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert lines == [
        f"mirror-avatar: error: {bad}: blocks[0].conditions[1].game: 'duet' is not allowed "
        "(give one of solo, leader_follower, joint, group)"
    ], result.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.long
def test_a_protocol_without_a_seed_is_served_with_a_warning_naming_the_drawn_seed(tmp_path):
    unseeded = tmp_path / "unseeded.toml"
    unseeded.write_text(PROTOCOL.replace("seed = 7\n", ""))
    server = subprocess.Popen(
        [Path(sys.executable).parent / "mirror-avatar", "lab", "--port", "0", "--no-lsl",
         "--out", str(tmp_path / "out"), "--protocol", str(unseeded)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    try:
        printed = []
        for line in server.stdout:  # type: ignore[union-attr]
            printed.append(line)
            if "console:" in line:  # printed after the warning
                break
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(server.pid, signal.SIGTERM)
        _, errors = server.communicate(timeout=30)
    shown = next(line for line in printed if line.startswith("protocol "))
    seed = re.search(r"seed (\d+)", shown).group(1)  # type: ignore[union-attr]
    assert (
        f"warning: {unseeded} has no seed: add 'seed = {seed}' to it, or a restart draws "
        "another and the participants' runs cannot resume"
    ) in errors.splitlines()


def start_server(out: Path, protocol_file: Path) -> tuple[subprocess.Popen[str], str, str]:
    server = subprocess.Popen(
        [Path(sys.executable).parent / "mirror-avatar", "lab", "--port", "0", "--out", str(out),
         "--no-lsl", "--protocol", str(protocol_file)],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, start_new_session=True,
    )  # fmt: skip
    for line in server.stdout:  # type: ignore[union-attr]
        if found := re.search(r"console: (http://[^/]+)/console\?token=(\S+)", line):
            return server, found.group(1), found.group(2)
    raise AssertionError("the server printed no console link")


def kill(server: subprocess.Popen[str]) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(server.pid, signal.SIGKILL)
    server.wait(10)
    server.stdout.close()  # type: ignore[union-attr]


@pytest.mark.long
def test_a_server_killed_mid_protocol_resumes_at_the_next_trial(tmp_path, protocol_file):
    out = tmp_path / "out"
    server, url, token = start_server(out, protocol_file)
    headers = {"Authorization": f"Bearer {token}"}
    try:
        created = create_participant(url, 0, headers)
        sid = created["id"]
        pages = [AnsweringPage(created["links"]["P1"]), AnsweringPage(created["links"]["P2"])]

        def on_trial_two() -> bool:
            trial = httpx.get(f"{url}/api/sessions/{sid}", headers=headers).json()["trial"]
            return trial is not None and trial["n"] == 2 and trial["progress"] > 0.2

        async def scenario() -> None:
            tasks = [asyncio.create_task(page.play(40.0)) for page in pages]
            await welcomed(pages)
            await asyncio.to_thread(
                httpx.post, f"{url}/api/sessions/{sid}/start", json={"force": True},
                headers=headers,
            )  # fmt: skip
            await asyncio.to_thread(wait_for, on_trial_two)
            os.killpg(server.pid, signal.SIGKILL)
            await asyncio.gather(*tasks)

        asyncio.run(scenario())
    finally:
        kill(server)
    folder = out / sid
    first = (folder / "trial-01_session.csv").read_bytes()
    interrupted = load_session(folder / "trial-02_session.csv")
    assert interrupted.metadata["complete"] is False and interrupted.n_samples > 10
    second_size = (folder / "trial-02_session.csv").stat().st_size

    server, url, token = start_server(out, protocol_file)
    headers = {"Authorization": f"Bearer {token}"}
    try:
        resumed = create_participant(url, 0, headers)
        assert resumed["id"] == sid and resumed["next_trial"] == 3
        assert any("resumed at trial 3 of 3" in event for event in resumed["events"])
        pages = [AnsweringPage(resumed["links"]["P1"]), AnsweringPage(resumed["links"]["P2"])]

        async def finish() -> None:
            tasks = [asyncio.create_task(page.play(20.0)) for page in pages]
            await welcomed(pages)
            await asyncio.to_thread(
                httpx.post, f"{url}/api/sessions/{sid}/start", json={"force": True},
                headers=headers,
            )  # fmt: skip
            await asyncio.to_thread(
                wait_for,
                lambda: (
                    httpx.get(f"{url}/api/sessions/{sid}", headers=headers).json()["state"]
                    == "finished"
                ),
            )
            await asyncio.gather(*tasks)

        asyncio.run(finish())
    finally:
        kill(server)
    assert (folder / "trial-01_session.csv").read_bytes() == first
    assert (folder / "trial-02_session.csv").stat().st_size == second_size
    last = load_session(folder / "trial-03_session.csv")
    final = load_protocol(protocol_file).schedule(0)[-1].name
    assert last.metadata["complete"] and last.metadata["lab"]["protocol_condition"] == final
    assert last.metadata["lab"]["condition_trial"] == (2 if final == "together" else 1)
    assert not (folder / "trial-04_session.csv").exists()


DELAYED = """
title = "delayed partner"
seed = 1

[[blocks]]
name = "delay"

[[blocks.conditions]]
name = "late and hidden"
game = "joint"
players = [
  { label = "P1", kind = "person" },
  { label = "A1", kind = "avatar", spec = "bundled:slow" },
]
trials = 1
duration = 3
delay = 0.3
occlude = [[1.5, 2.1]]
"""


def played_alone(protocol_file: Path) -> tuple[Session, Page]:
    """Play participant 0's run of a one-person protocol with one page: its first trial, page."""
    with protocol_lab(protocol_file) as lab:
        created = create_participant(lab.url, 0, BEARER)
        sid = created["id"]
        page = Page(created["links"]["P1"])

        async def scenario() -> None:
            task = asyncio.create_task(page.play(30.0))
            await welcomed([page])
            await asyncio.to_thread(command, lab, sid, "start")
            await asyncio.to_thread(wait_for, lambda: status(lab, sid)["state"] == "finished")
            await task

        asyncio.run(scenario())
    return load_session(protocol_file.parent / "out" / sid / "trial-01_session.csv"), page


def test_the_partner_is_drawn_late_and_hidden_as_the_condition_says(tmp_path):
    path = tmp_path / "delayed.toml"
    path.write_text(DELAYED)
    trial, page = played_alone(path)
    lab_meta = trial.metadata["lab"]
    assert lab_meta["partner_delay_s"] == pytest.approx(0.3)
    assert lab_meta["occluded_s"] == [[1.5, 2.1]]
    lag = 10  # 0.3 s of T = 0.03 s
    frames = page.of_type("frame")
    assert len(frames) > 50
    hidden = shown = 0
    for frame in frames:
        k = frame["k"]
        own, partner = frame["x"]
        assert own == trial.positions[0, k]  # the page's own point is not delayed
        if k < lag or 1.5 <= k * 0.03 < 2.1:
            assert partner is None
            hidden += 1
        else:
            assert partner == trial.positions[1, k - lag]  # exactly 10 samples late
            shown += 1
    assert hidden > 5 and shown > 20


JITTERED = DELAYED.replace(
    "occlude = [[1.5, 2.1]]", 'delay_jitter = 0.06\njitter_distribution = "exponential"'
).replace("duration = 3", "duration = 6")
"""A partner drawn 0.3 s late on average, the delay jittered (SD 0.06 s, skewed to long)."""


def test_the_partner_delay_is_jittered_in_order_as_the_condition_says(tmp_path):
    path = tmp_path / "jittered.toml"
    path.write_text(JITTERED)
    trial, page = played_alone(path)
    view = trial.metadata["lab"]["partner_view"]
    assert (view["jitter_s"], view["jitter_distribution"]) == (0.06, "exponential")
    drawn = []  # (k, the sample drawn) of each frame after the first second, found by value
    for frame in page.of_type("frame"):
        k, partner = frame["k"], frame["x"][1]
        if k >= 34 and partner is not None:
            drawn.append((k, int(np.flatnonzero(trial.positions[1, : k + 1] == partner)[-1])))
    ks, samples = np.array(drawn).T
    ages = ks - samples
    assert len(ages) > 100
    assert ages.min() >= 0 and ages.max() <= 10 + 8  # 4 SDs: 8 samples past the 10 of 0.3 s
    assert (np.diff(samples) >= 0).all()  # in order: never an older sample than the one before
    # jittered around 10 samples (an SD of 2), longer where a late sample holds those behind it
    print(f"ages: mean {ages.mean():.2f}, SD {ages.std():.2f}, median {np.median(ages)}")
    assert 1.0 < ages.std() < 3.0 and 10.0 <= ages.mean() <= 13.0
