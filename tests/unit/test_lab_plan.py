"""Lab session plans: what the console may ask for, and the roles and graphs that follow."""

from __future__ import annotations

import numpy as np
import pytest

from mirror_avatar.lab.design.plan import (
    LSL_SETTINGS,
    SESSION_SETTINGS,
    TRIAL_SETTINGS,
    LslDevice,
    PlanError,
    parse_plan,
)
from mirror_avatar.sessions.graphs import ring_graph

PERSON = {"label": "P1", "kind": "human"}
AVATAR = {"label": "A1", "kind": "avatar", "spec": "bundled:slow"}


def test_leader_follower_roles_follow_the_leader_index():
    plan = parse_plan({"condition": "leader_follower", "players": [AVATAR, PERSON], "leaders": [0]})
    assert plan.roles == ("leader", "follower")
    assert plan.humans == (1,)
    assert plan.graph.tolist() == [[0, 1], [1, 0]]
    assert (plan.duration, plan.trials, plan.pause, plan.on_drop) == (60.0, 1, 5.0, "continue")


def test_group_on_a_ring_with_a_leader():
    players = [PERSON, AVATAR, {**PERSON, "label": "P2"}, {**AVATAR, "label": "A2"}]
    plan = parse_plan({"condition": "group", "players": players, "graph": "ring", "leaders": [2]})
    assert plan.roles == ("group", "group", "group_leader", "group")
    np.testing.assert_array_equal(plan.graph, ring_graph(4))
    assert plan.neighbours(0) == [1, 3]


def test_group_takes_an_adjacency_matrix():
    players = [PERSON, AVATAR, {**PERSON, "label": "P2"}]
    plan = parse_plan(
        {"condition": "group", "players": players, "graph": [[0, 1, 0], [1, 0, 1], [0, 1, 0]]}
    )
    assert plan.neighbours(1) == [0, 2]


def test_solo_has_no_coupling():
    plan = parse_plan({"condition": "solo", "players": [PERSON, {**PERSON, "label": "P2"}]})
    assert plan.roles == ("solo", "solo") and not plan.graph.any()


def test_lsl_device_and_its_unit_mapping():
    person = {**PERSON, "device": "lsl", "lsl": {"stream": "hand", "channel": 2, "scale": 1 / 600}}
    plan = parse_plan({"condition": "joint", "players": [person, AVATAR]})
    assert plan.slots[0].lsl == LslDevice("hand", 2, 1 / 600, 0.0)


def test_plan_round_trips_through_json():
    players = [PERSON, AVATAR, {**PERSON, "label": "P2"}]
    plan = parse_plan({"condition": "group", "players": players, "graph": "path", "seed": 7})
    again = parse_plan(plan.to_json() | {"players": plan.to_json()["slots"]})
    assert again.to_json() == plan.to_json()


@pytest.mark.parametrize(
    ("plan", "problem"),
    [
        ([], "JSON object"),
        ({"condition": "dance", "players": [PERSON]}, "condition"),
        ({"condition": "joint", "players": [PERSON]}, "exactly two"),
        ({"condition": "leader_follower", "players": [PERSON, AVATAR]}, "one leader"),
        ({"condition": "solo", "players": [PERSON, AVATAR]}, "people only"),
        ({"condition": "joint", "players": [AVATAR, {**AVATAR, "label": "A2"}]}, "one person"),
        ({"condition": "joint", "players": [PERSON, {**PERSON}]}, "two players are labelled"),
        ({"condition": "joint", "players": [{**PERSON, "label": "../x"}, AVATAR]}, "label"),
        ({"condition": "joint", "players": [PERSON, {**AVATAR, "spec": ""}]}, "spec"),
        ({"condition": "joint", "players": [PERSON, AVATAR], "duration": 0.5}, "duration"),
        ({"condition": "joint", "players": [PERSON, AVATAR], "trials": 1.5}, "whole number"),
        ({"condition": "joint", "players": [PERSON, AVATAR], "pause": "5"}, "number"),
        ({"condition": "joint", "players": [PERSON, AVATAR], "show_metrics": 1}, "true or"),
        ({"condition": "joint", "players": [PERSON, AVATAR], "on_drop": "x"}, "on_drop"),
        ({"condition": "joint", "players": [PERSON, AVATAR], "leaders": [5]}, "leaders"),
        ({"condition": "group", "players": [PERSON, AVATAR], "graph": "random"}, "graph"),
        ({"condition": "group", "players": [PERSON, AVATAR], "graph": [[0, 1], [1, 1]]}, "diag"),
        ({"condition": "joint", "players": [{**PERSON, "device": "lsl"}, AVATAR]}, "stream"),
        ({"condition": "joint", "players": [PERSON] * 17}, "1 to 16"),
    ],
)
def test_bad_plans_are_refused_in_one_line(plan, problem):
    with pytest.raises(PlanError, match=problem) as caught:
        parse_plan(plan)
    assert "\n" not in str(caught.value) and str(caught.value).startswith("plan:")
    assert str(caught.value).startswith(f"plan: {caught.value.key}: {caught.value.what} (")


@pytest.mark.parametrize(
    ("key", "value"),
    [(s.key, value) for s in TRIAL_SETTINGS + SESSION_SETTINGS + LSL_SETTINGS
     for value in s.constraint.refused()],  # type: ignore[union-attr]
    ids=str,
)  # fmt: skip
def test_every_value_a_declared_key_refuses_is_refused_naming_the_key(key, value):
    plan: dict = {"condition": "joint", "players": [PERSON, AVATAR]}
    where = key
    if key in {s.key for s in LSL_SETTINGS}:
        plan["players"] = [{**PERSON, "device": "lsl", "lsl": {"stream": "hand", key: value}},
                           AVATAR]  # fmt: skip
        where = f"players[0].lsl.{key}"
    else:
        plan[key] = value
    with pytest.raises(PlanError) as caught:
        parse_plan(plan)
    assert caught.value.key == where and caught.value.what == f"{value!r} is not allowed"
