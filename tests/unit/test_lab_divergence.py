"""An avatar diverging mid-trial on the lab's clock ends the trial, saying who and when, in the
trial's sidecar and the console's log; the samples recorded before stay finite."""

from __future__ import annotations

import asyncio
import json
import time

import numpy as np

from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.running.runner import LabSession
from mirror_avatar.lab.running.schedule import OnePlan
from mirror_avatar.players.base import Observation, Player
from mirror_avatar.sessions.loading import load_session
from waiting import wait_for

DYAD = {
    "condition": "leader_follower",
    "duration": 3.0,
    "trials": 2,
    "pause": 0.0,
    "leaders": [0],
    "players": [
        {"label": "P1", "kind": "human"},
        {"label": "A1", "kind": "avatar", "spec": "hkb"},
    ],
}


class Unstable(Player):
    """An avatar whose position grows 1e100-fold every period from sample 20: 1e100 at sample 24."""

    label = "unstable"

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        self.x = 1e-300
        return 0.0, 0.0

    def step(self, observation: Observation) -> tuple[float, float]:
        if observation.k >= 20:
            self.x *= 1e100
        return (self.x if observation.k >= 20 else 0.0), 0.0


def test_a_diverging_avatar_ends_the_trial_naming_it_and_the_sample(tmp_path):
    async def scenario() -> LabSession:
        session = LabSession(
            "S1", OnePlan(parse_plan(DYAD)), tmp_path / "S1", time.monotonic, countdown=0
        )
        session.avatars = {1: Unstable()}
        assert session.start(force=True) is None
        await asyncio.to_thread(
            wait_for, lambda: session.state == "finished" or session.error is not None, 30.0
        )
        return session

    session = asyncio.run(scenario())
    message = (
        "player 1 (A1): diverged at sample 24 (0.72 s): it returned position 1e+100 and "
        "velocity 0.0, not finite or beyond 1e+06; the session ends there (give its spec "
        "parameters nearer their defaults)"
    )
    first, second = session.results
    assert (first["complete"], first["end_reason"], first["n_samples"]) == (False, message, 24)
    assert first["diverged"] == {"sample": 24, "player": 1, "label": "A1", "message": message}
    assert second["end_reason"] == message  # the next trial plays (and ends) the same way
    assert f"trial 1 ended: {message}" in [event[9:] for event in session.events]
    sidecar = json.loads((tmp_path / "S1" / "trial-01_session.json").read_text())
    assert sidecar["metadata"]["diverged"]["sample"] == 24 and not sidecar["metadata"]["complete"]
    recorded = load_session(tmp_path / "S1" / "trial-01_session.csv")
    assert recorded.n_samples == 24 and np.isfinite(recorded.positions).all()


class Broken(Player):
    """An avatar whose reset returns no position."""

    label = "broken"

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        return float("nan"), 0.0

    def step(self, observation: Observation) -> tuple[float, float]:
        return 0.0, 0.0


def test_an_avatar_diverging_at_reset_closes_the_trial_and_the_next_start_opens_the_next(tmp_path):
    async def scenario() -> tuple[LabSession, str]:
        plan = parse_plan(DYAD | {"trials": 3})
        session = LabSession("S2", OnePlan(plan), tmp_path / "S2", time.monotonic, countdown=0)
        session.avatars = {1: Broken()}
        assert session.start(force=True) is None
        await asyncio.to_thread(wait_for, lambda: session.error is not None, 30.0)
        error = session.error
        session.avatars = {1: Unstable()}
        assert session.start(force=True) is None
        await asyncio.to_thread(wait_for, lambda: bool(session.results), 30.0)
        await session.stop()
        return session, error

    session, error = asyncio.run(scenario())
    assert error.startswith("cannot run: player 1 (A1): diverged at sample 0 (0.00 s)"), error
    first = json.loads((tmp_path / "S2" / "trial-01_session.json").read_text())["metadata"]
    assert first["diverged"]["sample"] == 0 and not first["complete"]
    assert session.results[0]["lab"]["trial"] == 2
