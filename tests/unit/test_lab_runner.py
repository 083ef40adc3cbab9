"""A lab session's runner: stopping at any moment leaves every trial it opened closed and listed;
what the console and the end screens show of a trial's measures."""

from __future__ import annotations

import asyncio
import json
import time

from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.running.runner import LabSession, headline_measures, participant_measures
from mirror_avatar.lab.running.schedule import OnePlan

SOLO = {"condition": "solo", "duration": 5.0, "players": [{"label": "P1", "kind": "human"}]}


def test_a_stop_while_the_trial_opens_closes_it(tmp_path):
    async def scenario() -> LabSession:
        session = LabSession(
            "S1", OnePlan(parse_plan(SOLO)), tmp_path / "S1", time.monotonic, countdown=0
        )
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
        session = LabSession("S2", OnePlan(plan), tmp_path / "S2", time.monotonic, countdown=0)
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


def test_each_participant_is_told_who_led_in_their_own_words():
    measures = {"leader": 0, "co_confidence_rate": 0.25, "leader_lag_s": 0.3}
    assert participant_measures(measures, 0) == {"co_confidence_rate": 0.25, "led_by": "you"}
    assert participant_measures(measures, 1)["led_by"] == "partner"
    assert participant_measures(measures | {"leader": "none"}, 1)["led_by"] == "none"
    assert participant_measures({"jitter_index_player_0": 0.1}, 0) == {}  # a group or too short


def test_the_trial_list_keeps_the_headline_measures_and_every_p_value():
    measures = {
        "leader": 1, "leader_lag_s": 0.4, "co_confidence_rate": 0.5, "co_confidence_count": 2,
        "co_confidence_segments": [{"start": 0.0, "end": 3.0, "dv": 0.1, "dt": 0.05}],
        "jitter_index_player_0": 0.1, "jitter_index_player_1": 0.2, "synchrony_entries": 3,
        "leader_share_p_value": 0.05, "time_lag_p_value": 0.1, "surrogates": {"n": 19},
    }  # fmt: skip
    assert set(headline_measures(measures)) == {
        "leader", "leader_lag_s", "co_confidence_rate", "co_confidence_count",
        "jitter_index_player_0", "jitter_index_player_1", "leader_share_p_value",
        "time_lag_p_value", "surrogates",
    }  # fmt: skip
    assert headline_measures({"error": "ValueError: x"}) == {"error": "ValueError: x"}
