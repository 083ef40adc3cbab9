"""The events of an exported lab trial: its condition and every manipulation, from its record."""

from __future__ import annotations

from typing import Any

from mirror_avatar.files.trial_record import TrialRecord, trial_record
from mirror_avatar.lab.export.bids_events import EVENT_COLUMN_INFO, EVENT_COLUMNS, trial_events

T = 0.03


SLOTS = [{"label": "P1", "kind": "human", "role": "joint"},
         {"label": "A1", "kind": "avatar", "role": "joint"}]  # fmt: skip


def study(**lab: Any) -> dict[str, Any]:
    """A study trial's ``lab`` object, with ``lab``'s keys changed."""
    return {
        "session_id": "study-p001", "condition": "joint", "protocol": "p", "participant": 1,
        "block": "partners", "protocol_condition": "hidden", "condition_trial": 1,
        "partners": {}, "trial": 4, "slots": SLOTS, "partner_delay_s": 0.3, "occluded_s": [],
    } | lab  # fmt: skip


def study_metadata() -> TrialRecord:
    """A study trial's record: delayed, occluded twice, inputs lost, a perturbation."""
    return trial_record({
        "lab": study(occluded_s=[[10.0, 15.0], [25.0, 40.0], [50.0, 60.0]]),
        "input_events": [
            {"sample": 300, "label": "P2", "event": "lost", "seq": 120},
            {"sample": 330, "label": "P2", "event": "live", "seq": 121},
        ],
        "dropped": {"P1": 900},
        "perturbations": [
            {"sample": 500, "time_s": 15.0, "player": "A1", "change": "follower -> leader"},
            {"sample": 100, "time_s": 3.0, "player": "A1", "change": "gain 2"},
        ],
    })  # fmt: skip


def test_every_manipulation_is_an_event_in_order_of_onset() -> None:
    rows = trial_events(study_metadata(), n_samples=1000, period=T)  # 30 s recorded
    assert [set(row) for row in rows] == [set(EVENT_COLUMNS)] * len(rows)
    got = [(r["trial_type"], float(r["onset"]), float(r["duration"]), int(r["sample"]),
            r["player"], r["delay_s"], r["change"]) for r in rows]  # fmt: skip
    assert got == [
        ("trial", 0.0, 1000 * T, 0, "n/a", "n/a", "n/a"),
        ("delay", 0.0, 1000 * T, 0, "n/a", "0.3", "n/a"),
        ("perturbation", 100 * T, 0.0, 100, "A1", "n/a", "gain 2"),
        ("input_lost", 300 * T, 0.0, 300, "P2", "n/a", "n/a"),
        ("input_live", 330 * T, 0.0, 330, "P2", "n/a", "n/a"),
        ("occlusion", 10.0, 5.0, 334, "n/a", "n/a", "n/a"),
        ("perturbation", 15.0, 0.0, 500, "A1", "n/a", "follower -> leader"),
        ("occlusion", 25.0, 1000 * T - 25.0, 834, "n/a", "n/a", "n/a"),  # clipped to the end
        ("dropped", 900 * T, 0.0, 900, "P1", "n/a", "n/a"),
    ]  # the occlusion from 50 s, after the recording's end, is left out
    assert {(r["trial"], r["block"], r["condition"]) for r in rows} == {("4", "partners", "hidden")}


def test_a_trial_outside_a_study_has_its_lab_condition_and_no_block() -> None:
    lab = {"session_id": "s", "trial": 2, "condition": "group", "slots": SLOTS}
    (row,) = trial_events(trial_record({"lab": lab}), n_samples=10, period=T)
    assert (row["trial_type"], row["trial"], row["block"], row["condition"]) == (
        "trial", "2", "n/a", "group"
    )  # fmt: skip


def test_occlusions_backwards_or_after_the_recording_and_no_delay_are_left_out() -> None:
    lab = study(partner_delay_s=0.0, occluded_s=[[5, 2], [4, 4], [3.5, 9]])
    assert [r["trial_type"] for r in trial_events(trial_record({"lab": lab}), 100, T)] == ["trial"]


def test_every_column_and_event_type_is_described() -> None:
    assert set(EVENT_COLUMN_INFO) == set(EVENT_COLUMNS)
    levels = set(EVENT_COLUMN_INFO["trial_type"]["Levels"])
    assert {"trial", "delay", "occlusion", "input_lost", "input_live", "dropped",
            "perturbation"} == levels  # fmt: skip
