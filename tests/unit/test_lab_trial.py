"""One lab trial on the server's clock: players stepped, samples on disk as taken, inputs logged."""

from __future__ import annotations

import csv
import json
import math
import threading
import time

import numpy as np
import pytest

from mirror_avatar.engine.loop import Engine
from mirror_avatar.files import atomic
from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.running.trial import LabTrial, build_avatars
from mirror_avatar.realtime.inputs import BrowserInput, HumanPlayer
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.specs import load_player
from waiting import wait_for

RING = {
    "condition": "group",
    "graph": "ring",
    "duration": 3.0,
    "seed": 11,
    "players": [
        {"label": "P1", "kind": "human"},
        {"label": "A1", "kind": "avatar", "spec": "bundled:slow"},
        {"label": "P2", "kind": "human"},
        {"label": "A2", "kind": "avatar", "spec": "bundled:fast"},
    ],
}


def sway(k: int, phase: float = 0.0) -> float:
    return 0.3 * math.sin(2 * math.pi * 0.5 * k * 0.03 + phase)


def test_browser_input_keeps_the_newest_sample_and_renumbers_a_new_connection():
    source = BrowserInput()
    assert source.latest() is None
    source.put(0.1, 5)
    source.put(0.2, 3)  # older: ignored
    assert (source.latest().x, source.latest().seq) == (0.1, 5)
    source.reconnected()
    source.put(-0.2, 0)  # a new page counts from 0 again
    assert (source.latest().x, source.latest().seq) == (-0.2, 6)


def test_human_player_holds_and_counts_missing_samples():
    source = BrowserInput()
    person = HumanPlayer(source, "P1", period=0.03)
    assert person.reset() == (0.0, 0.0)
    assert person.current_state() == (0.0, 0.0) and person.last_input.held
    source.put(0.3, 0)
    x, v = person.current_state()
    assert (x, v) == (0.3, pytest.approx(10.0)) and not person.last_input.held
    assert person.current_state() == (0.3, 0.0) and person.last_input.held
    assert person.held == 2


def run_trial(tmp_path, plan_data, drop_at=None, skip=()):
    plan = parse_plan(plan_data)
    inputs = {k: BrowserInput() for k in plan.humans}
    published = []
    trial = LabTrial(
        plan,
        1,
        tmp_path,
        inputs,
        build_avatars(plan),
        time.monotonic,
        {"session_id": "S1", "condition": plan.condition},
        lambda positions, stamp: published.append((positions.copy(), stamp)),
    )
    while not trial.finished:
        k = trial.k
        for i, source in inputs.items():
            if k not in skip:
                source.put(sway(k, i), k)
        if k == drop_at:
            trial.mark_dropped("P2")
        trial.tick()
    return plan, trial, inputs, published


def test_a_ring_trial_is_recorded_sample_by_sample(tmp_path):
    plan, trial, _, published = run_trial(tmp_path, RING)
    summary = trial.finish(True, "completed")
    session = load_session(trial.session_path)
    assert session.n_samples == summary["n_samples"] == round(3.0 / 0.03) + 1
    assert session.labels == ("P1", "A1", "P2", "A2") and session.roles == ("group",) * 4
    np.testing.assert_array_equal(session.graph, plan.graph)
    np.testing.assert_array_equal(session.positions[0], [sway(k, 0) for k in range(101)])
    np.testing.assert_array_equal(session.positions[2], [sway(k, 2) for k in range(101)])
    assert summary["complete"] and summary["lab"]["slots"][1]["spec"] == "bundled:slow"
    assert 0 < summary["metrics"]["group_synchronisation"] <= 1
    published_x = np.array([p for p, _ in published])
    np.testing.assert_array_equal(published_x.T, session.positions)


def test_avatars_play_as_in_the_engine(tmp_path):
    """The avatars' trajectories are those of the engine's step loop with the same seeds."""
    plan, trial, _, _ = run_trial(tmp_path, RING)
    trial.finish(True, "completed")
    recorded = load_session(trial.session_path)
    sources = {k: BrowserInput() for k in plan.humans}
    players = [
        HumanPlayer(sources[k], slot.label) if slot.kind == "human"
        else load_player(slot.spec, plan.roles[k])
        for k, slot in enumerate(plan.slots)
    ]  # fmt: skip
    engine = Engine(players, plan.graph, plan.roles)
    engine.reset(trial.seed, trial.n_ticks)
    for k in range(trial.n_ticks - 1):
        for i, source in sources.items():
            source.put(sway(k, i), k)
        engine.step()
    for i, source in sources.items():
        source.put(sway(trial.n_ticks - 1, i), trial.n_ticks - 1)
    replay = engine.finish()
    np.testing.assert_array_equal(replay.positions, recorded.positions)


def test_missing_inputs_are_held_and_logged(tmp_path):
    _, trial, _, _ = run_trial(tmp_path, RING, skip=range(10, 20))
    summary = trial.finish(True, "completed")
    assert summary["held"] == {"P1": 10, "P2": 10}
    with trial.inputs_path.open() as file:
        rows = list(csv.DictReader(file))
    assert len(rows) == summary["n_samples"]
    held = [int(row["held_P2"]) for row in rows]
    assert held[10:20] == [1] * 10 and sum(held) == 10
    assert [int(row["seq_P1"]) for row in rows[9:21]] == [9] * 11 + [20]
    session = load_session(trial.session_path)
    assert np.all(session.positions[0, 10:20] == session.positions[0, 9])


def test_a_drop_is_in_the_sidecar_at_once_and_the_files_read_mid_trial(tmp_path):
    plan = parse_plan(RING | {"duration": 30.0})
    inputs = {k: BrowserInput() for k in plan.humans}
    lab = {"session_id": "S1", "condition": "group"}
    trial = LabTrial(plan, 2, tmp_path, inputs, build_avatars(plan), time.monotonic, lab)
    for k in range(50):
        for source in inputs.values():
            source.put(sway(k), k)
        trial.tick()
    trial.mark_dropped("P2")
    sidecar_path = trial.session_path.with_suffix(".json")
    wait_for(lambda: "P2" in json.loads(sidecar_path.read_text())["metadata"]["dropped"], 30)
    sidecar = json.loads(sidecar_path.read_text())
    assert sidecar["metadata"]["dropped"] == {"P2": 50}
    assert sidecar["metadata"]["complete"] is False
    assert trial.session_path.name == "trial-02_session.csv"
    assert load_session(trial.session_path).n_samples == 50
    assert not trial.finish(False, "stopped")["complete"]


def test_a_drop_written_to_a_slow_disk_holds_neither_its_caller_nor_the_clock(
    tmp_path, monkeypatch
):
    plan = parse_plan(RING | {"duration": 30.0})
    inputs = {k: BrowserInput() for k in plan.humans}
    lab = {"session_id": "S1", "condition": "group"}
    trial = LabTrial(plan, 1, tmp_path, inputs, build_avatars(plan), time.monotonic, lab)

    def tick(n: int) -> None:
        for _ in range(n):
            for source in inputs.values():
                source.put(sway(trial.k), trial.k)
            trial.tick()

    tick(10)
    disk_answers = threading.Event()
    write = atomic.write_atomic_bytes

    def slow_disk(path, data):
        disk_answers.wait(60)
        write(path, data)

    monkeypatch.setattr(atomic, "write_atomic_bytes", slow_disk)
    dropping = threading.Thread(target=trial.mark_dropped, args=("P2",))
    ticking = threading.Thread(target=tick, args=(5,))
    try:
        dropping.start()
        dropping.join(10)
        ticking.start()
        ticking.join(10)
        assert not dropping.is_alive() and not ticking.is_alive()
        assert trial.k == 15 and trial.dropped == {"P2": 10}
    finally:
        disk_answers.set()
        dropping.join(60)
        ticking.join(60)
    summary = trial.finish(False, "stopped")
    assert summary["dropped"] == {"P2": 10}
    sidecar = json.loads(trial.session_path.with_suffix(".json").read_text())
    assert sidecar["metadata"]["dropped"] == {"P2": 10} and sidecar["n_samples"] == 15


def test_recent_positions_and_group_synchronisation(tmp_path):
    _, trial, _, _ = run_trial(tmp_path, RING)
    recent = trial.recent(1.0)
    assert len(recent["times"]) == len(recent["positions"][0]) == 33
    assert recent["group_sync"] is None or 0 <= recent["group_sync"] <= 1
    assert 0 < trial.recent(10.0)["group_sync"] <= 1
    trial.finish(True, "completed")
