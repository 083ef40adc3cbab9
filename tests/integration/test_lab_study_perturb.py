"""A perturbation mid-trial through the real lab server: a following avatar switched to leading
at one sample of a participant's run, seen in the recording against the recorded person."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
from test_lab_server import BEARER, TOKEN, Page, status
from test_lab_study import play_to_the_end

from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.players.base import Observation, Player
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.sessions.session import Session
from mirror_avatar.specs import load_player
from mirror_avatar.testing import ServerThread

SWITCH_S, SWITCH = 3.0, 100
"""When the avatar is switched (s) and the sample that is (3.0 / 0.03)."""

PROTOCOL = f"""
title = "switch"
seed = 11

[[blocks]]
name = "dyad"

[[blocks.conditions]]
name = "switch"
game = "leader_follower"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "A1", kind = "avatar", spec = "bundled:slow" }},
]
leaders = ["P1"]
trials = 1
duration = 6
pause = 0.5
perturb = [{{ at = {SWITCH_S}, player = "A1", set = "leader" }}]
"""


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[ServerThread]:
    path = tmp_path / "switch.toml"
    path.write_text(PROTOCOL)
    # A tick of this busy test process may take long; ending the trial for it is not tested here.
    settings = LabSettings(
        out_dir=tmp_path / "out",
        token=TOKEN,
        countdown=1,
        protocol=load_protocol(path),
        max_tick=10.0,
    )
    with ServerThread(create_lab_app(settings)) as running:
        yield running


def replay(
    session: Session,
    players: list[Player],
    switch: int | None,
    person: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Step the avatar against the recorded person (or ``person``'s positions and velocities),
    handing over to ``players[1]`` at ``switch``; return its positions."""
    person_x, person_v = person or (session.positions[0], session.velocities[0])
    avatar = players[0]
    x = [avatar.reset(seed=session.metadata["player_seeds"][1])[0]]
    players[1].reset(seed=session.metadata["player_seeds"][1])
    for k in range(session.n_samples - 1):
        if k == switch:
            players[1].take_over(avatar)
            avatar = players[1]
        seen = Observation.of_partner(k, person_x[k], person_v[k], person_x[max(k - 1, 0)])
        x.append(avatar.step(seen)[0])
    return np.array(x)


def test_an_avatar_switched_from_following_to_leading_changes_at_that_sample(lab, tmp_path):
    created = httpx.post(f"{lab.url}/api/sessions", json={"participant": 0}, headers=BEARER)
    assert created.status_code == 201, created.text
    sid = created.json()["id"]
    page = Page(created.json()["links"]["P1"])
    play_to_the_end(lab, sid, [page], 30.0)
    events = status(lab, sid)["events"]
    assert any(e.endswith(f"A1 role=leader at sample {SWITCH} of trial 1") for e in events)
    folder = tmp_path / "out" / sid
    session = load_session(folder / "trial-01_session.csv")
    sidecar = json.loads((folder / "trial-01_session.json").read_text())["metadata"]
    assert sidecar["complete"] and session.n_samples == 201
    assert sidecar["perturbations"] == [
        {"sample": SWITCH, "time_s": SWITCH_S, "player": "A1", "change": "role=leader"}
    ]
    recorded = session.positions[1]
    # Independent replay: the follower, handed over to the leader at the sample, against the
    # recorded person gives the recording bit for bit; the follower alone parts from it at
    # the first sample the leader stepped to, and not before.
    switched = replay(
        session, [load_player("bundled:slow", r) for r in ("follower", "leader")], SWITCH
    )
    np.testing.assert_array_equal(switched, recorded)
    follower = replay(session, [load_player("bundled:slow", "follower")] * 2, None)
    parted = np.flatnonzero(follower != recorded)
    assert parted[0] == SWITCH + 1
    # Following, the avatar stays near the person; leading, it goes its own way. Shown against
    # the page's own sine at the sample times: the person recorded is that sine as the busy
    # test process sent it, held for a tick or more when the page's sends came late.
    w = 2 * np.pi * 0.5  # the page's motion: `Page.x`
    person = 0.3 * np.sin(w * session.times), 0.3 * w * np.cos(w * session.times)
    avatar = replay(
        session, [load_player("bundled:slow", r) for r in ("follower", "leader")], SWITCH, person
    )
    settle = 50  # 1.5 s for each role's motion to settle
    before = slice(settle, SWITCH + 1)
    after = slice(SWITCH + 1 + settle, None)
    rms = [float(np.sqrt(np.mean((avatar[s] - person[0][s]) ** 2))) for s in (before, after)]
    assert rms[1] > 2 * rms[0], rms
    correlation = [float(np.corrcoef(avatar[s], person[0][s])[0, 1]) for s in (before, after)]
    assert correlation[0] > 0.8 > correlation[1] + 0.3, correlation
