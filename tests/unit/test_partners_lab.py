"""Partners from the literature as avatars of a lab trial on the server's clock."""

from __future__ import annotations

import math
import time

import numpy as np

from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.running.trial import LabTrial, build_avatars
from mirror_avatar.realtime.inputs import BrowserInput
from mirror_avatar.sessions.loading import load_session

GROUP = {
    "condition": "group",
    "graph": "complete",
    "duration": 3.0,
    "seed": 5,
    "players": [
        {"label": "P1", "kind": "human"},
        {"label": "A1", "kind": "avatar", "spec": "adaptive"},
        {"label": "A2", "kind": "avatar", "spec": "kuramoto:omega=2.5"},
        {"label": "A3", "kind": "avatar", "spec": "rpc"},
        {"label": "A4", "kind": "avatar", "spec": "hkb"},
        {"label": "A5", "kind": "avatar", "spec": "excitator:b=0.5"},
    ],
}


def test_partners_play_a_lab_group_trial(tmp_path) -> None:  # type: ignore[no-untyped-def]
    plan = parse_plan(GROUP)
    inputs = {k: BrowserInput() for k in plan.humans}
    trial = LabTrial(
        plan, 1, tmp_path, inputs, build_avatars(plan), time.monotonic,
        {"session_id": "S1", "condition": plan.condition}, None,
    )  # fmt: skip
    while not trial.finished:
        inputs[0].put(0.3 * math.sin(math.pi * trial.k * 0.03), trial.k)
        trial.tick()
    summary = trial.finish(True, "completed")
    session = load_session(trial.session_path)
    assert summary["complete"] and session.n_players == 6
    assert [p["class"] for p in session.metadata["players"][1:]] == [
        "AdaptivePlayer", "KuramotoPlayer", "ReactivePredictivePlayer", "HKBPartner",
        "ExcitatorPartner",
    ]  # fmt: skip
    assert np.all(np.isfinite(session.positions)) and np.all(np.ptp(session.positions, axis=1) > 0)
    assert 0 < summary["metrics"]["group_synchronisation"] <= 1
