"""A lab session's runner: stopping at any moment leaves every trial it opened closed and listed."""

from __future__ import annotations

import asyncio
import json
import time

from mirror_avatar.lab.plan import parse_plan
from mirror_avatar.lab.runner import LabSession

SOLO = {"condition": "solo", "duration": 5.0, "players": [{"label": "P1", "kind": "human"}]}


def test_a_stop_while_the_trial_opens_closes_it(tmp_path):
    async def scenario() -> LabSession:
        session = LabSession("S1", parse_plan(SOLO), tmp_path / "S1", time.monotonic, countdown=0)
        opening = session._new_trial

        def slow_open(n: int):
            time.sleep(0.5)  # a slow disk: the researcher presses Stop meanwhile
            return opening(n)

        session._new_trial = slow_open  # type: ignore[method-assign]
        assert session.start(force=True) is None
        await asyncio.sleep(0.2)
        await session.stop()
        return session

    session = asyncio.run(scenario())
    assert session.trial is None and session.state == "waiting" and session.next_trial == 2
    (result,) = session.results
    assert result["end_reason"] == "stopped by the researcher" and not result["complete"]
    sidecar = json.loads((tmp_path / "S1" / "trial-01_session.json").read_text())
    assert sidecar["metadata"]["end_reason"] == "stopped by the researcher"


def test_a_stop_mid_trial_saves_it_and_the_next_start_plays_the_next_trial(tmp_path):
    async def scenario() -> LabSession:
        plan = parse_plan(SOLO | {"duration": 2.0, "trials": 2, "pause": 0.0})
        session = LabSession("S2", plan, tmp_path / "S2", time.monotonic, countdown=0)
        assert session.start(force=True) is None
        while session.state != "running":
            await asyncio.sleep(0.01)
        await asyncio.sleep(0.5)
        await session.stop()
        assert session.start(force=True) is None
        while session.state != "finished":
            await asyncio.sleep(0.05)
        return session

    session = asyncio.run(scenario())
    first, second = session.results
    assert not first["complete"] and 5 < first["n_samples"] < 68
    assert (
        second["complete"]
        and second["n_samples"] == round(2.0 / 0.03) + 1
        and second["lab"]["trial"] == 2
    )
