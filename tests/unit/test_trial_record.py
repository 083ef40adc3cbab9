"""The trial record: one declared format of a lab trial's sidecar, written and read back equal,
reading every file the lab has written (version 1), refusing a damaged one in one line naming
the file and the key."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trial_record import (
    KIND_NAMES,
    KINDS,
    InputEventRecord,
    PerturbationRecord,
    SlotRecord,
    StudyRecord,
    TrialRecord,
    lab_trial_record,
    partner_kind,
    read_trial_record,
    trial_record,
)
from mirror_avatar.sessions.session import make_sidecar

texts = st.text(min_size=1, max_size=8)
counts = st.integers(min_value=0, max_value=2**32 - 1)
seconds = st.floats(min_value=0, max_value=1e4, allow_nan=False)
slots = st.builds(
    SlotRecord,
    label=texts,
    kind=st.sampled_from(KINDS),
    role=st.sampled_from(["leader", "follower", "joint", "solo"]),
    spec=st.none() | texts,
    device=st.none() | st.sampled_from(["pointer", "lsl"]),
    input=st.none() | st.dictionaries(texts, counts, max_size=3),
)
studies = st.builds(
    StudyRecord,
    protocol=texts,
    participant=counts,
    block=texts,
    condition=texts,
    condition_trial=counts,
    delay_s=seconds,
    occluded_s=st.lists(st.tuples(seconds, seconds), max_size=3).map(tuple),
    partners=st.dictionaries(texts, st.sampled_from(KINDS), max_size=4),
)
records = st.builds(
    TrialRecord,
    session_id=texts,
    trial=counts,
    condition=st.sampled_from(["solo", "leader_follower", "joint", "group", ""]),
    slots=st.lists(slots, min_size=1, max_size=4).map(tuple),
    study=st.none() | studies,
    seed=st.none() | counts,
    created_utc=st.none() | texts,
    started_utc=st.none() | texts,
    complete=st.booleans(),
    dropped=st.dictionaries(texts, counts, max_size=2),
    perturbations=st.lists(
        st.builds(
            PerturbationRecord,
            sample=counts,
            time_s=seconds,
            player=texts,
            change=st.text(max_size=20),
        ),
        max_size=3,
    ).map(tuple),  # fmt: skip
    held=st.dictionaries(texts, counts, max_size=2),
    input_events=st.lists(
        st.builds(
            InputEventRecord,
            sample=counts,
            label=texts,
            event=st.sampled_from(["lost", "live"]),
            seq=st.none() | counts,
        ),
        max_size=3,
    ).map(tuple),  # fmt: skip
    clock=st.none() | texts,
    files=st.dictionaries(st.sampled_from(["inputs", "answers"]), texts, max_size=2),
)


@given(records)
def test_a_record_written_and_read_back_is_equal(record: TrialRecord) -> None:
    written = json.loads(json.dumps(record.metadata_json()))
    assert trial_record(written) == record


def test_a_sidecar_the_lab_wrote_is_read_as_its_record(tmp_path: Path) -> None:
    lab = {
        "session_id": "protocol-p003", "condition": "joint", "partner_delay_s": 0.3,
        "occluded_s": [[10, 15]], "protocol": "Following", "participant": 3,
        "block": "partners", "protocol_condition": "hidden", "condition_trial": 2,
        "partners": {"P1": "human", "A1": "avatar"}, "trial": 7,
        "slots": [
            {"label": "P1", "kind": "human", "role": "joint", "spec": None, "device": "lsl",
             "input": {"source_id": "hand", "invalid": 0}},
            {"label": "A1", "kind": "avatar", "role": "joint", "spec": "bundled:slow",
             "device": None},
        ],
    }  # fmt: skip
    change = {"sample": 40, "time_s": 1.2, "player": "A1", "change": "coupling"}
    event = {"sample": 41, "label": "P1", "event": "lost", "seq": 39}
    metadata = {"lab": lab, "seed": 5, "created_utc": "c", "started_utc": "s", "complete": True,
                "dropped": {"P1": 40}, "perturbations": [change], "held": {"P1": 3},
                "input_events": [event], "clock": "local_clock",
                "files": {"inputs": "trial-07_inputs.csv"}}  # fmt: skip
    path = tmp_path / "trial-07_session.json"
    path.write_text(json.dumps(make_sidecar(["P1", "A1"], ["joint"] * 2, [[0, 1], [1, 0]], 0.03,
                                            metadata)))  # fmt: skip
    record = read_trial_record(path)
    assert record.lab_json() == lab
    assert record.study is not None and record.study.occluded_s == ((10, 15),)
    assert record.perturbations[0].player == "A1" and record.dropped == {"P1": 40}
    assert [s.label for s in record.partners_of("P1")] == ["A1"]
    assert record.held == {"P1": 3} and record.input_events[0].to_json() == event
    assert record.clock == "local_clock" and record.files["inputs"] == "trial-07_inputs.csv"
    assert record.block == "partners" and record.named_condition == "hidden"
    assert {k: v for k, v in record.metadata_json().items()} == metadata


def test_an_early_recording_keeps_its_creation_time_in_the_lab_object() -> None:
    lab = {"session_id": "s", "condition": "solo", "created_utc": "2026-11-01T10:00:00",
           "trial": 1, "slots": [{"label": "P1", "kind": "human", "role": "solo"}]}  # fmt: skip
    record = trial_record({"lab": lab})
    assert record.created_utc == "2026-11-01T10:00:00" and record.block is None
    assert record.named_condition == "solo"


def test_a_session_of_another_source_has_no_lab_record() -> None:
    assert lab_trial_record({"seed": 3}) is None


def _page(interruptions: list[dict[str, object]]) -> dict[str, object]:
    """A page's record in a sidecar with these interruptions."""
    page = {"exchanges": 0, "rtt_ms": {}, "offset_ms": None, "uncertainty_ms": None}
    return page | {"sample_rate_hz": None, "frame_rate_hz": None, "interruptions": interruptions}


@pytest.mark.parametrize(
    ("damage", "problem"),
    [
        (lambda m: m["lab"].pop("session_id"), "metadata.lab.session_id: None is not a text"),
        (lambda m: m["lab"].update(trial="7"), "metadata.lab.trial: '7' is not a whole number"),
        (lambda m: m["lab"]["slots"][0].update(kind="robot"),
         "metadata.lab.slots[0].kind: 'robot' is not one of human, avatar"),
        (lambda m: m["lab"].update(partner_delay_s="late"),
         "metadata.lab.partner_delay_s: 'late' is not a finite number"),
        (lambda m: m.update(perturbations={}), "metadata.perturbations: is not a list"),
        (lambda m: m.update(held={"P1": -1}), "metadata.held.P1: -1 is not a whole number"),
        (lambda m: m.update(input_events=[{"sample": 3, "label": "P1"}]),
         "metadata.input_events[0].event: None is not a text"),
        (lambda m: m.update(pages={"P1": _page([{"kind": "minimised", "start_s": 1,
                                                  "end_s": 2}])}),
         "metadata.pages.P1.interruptions[0].kind: 'minimised' is not one of hidden, blur"),
        (lambda m: m.update(pages={"P1": _page([{"kind": "hidden", "start_s": 2, "end_s": 1}])}),
         "metadata.pages.P1.interruptions[0].end_s: is before start_s"),
    ],
)  # fmt: skip
def test_a_damaged_record_is_one_line_naming_the_file_and_key(tmp_path, damage, problem):
    lab = {"session_id": "s", "condition": "joint", "partner_delay_s": 0.0, "occluded_s": [],
           "protocol": "p", "participant": 0, "block": "b", "protocol_condition": "c",
           "condition_trial": 1, "partners": {}, "trial": 7,
           "slots": [{"label": "P1", "kind": "human", "role": "solo"}]}  # fmt: skip
    metadata = {"lab": lab, "perturbations": []}
    damage(metadata)
    path = tmp_path / "trial-07_session.json"
    path.write_text(json.dumps({"metadata": metadata}))
    with pytest.raises(InputError) as raised:
        read_trial_record(path)
    assert str(raised.value).count("\n") == 0
    assert str(path) in str(raised.value) and problem in str(raised.value)


def test_partner_kinds_name_persons_avatars_mixed_or_none() -> None:
    assert partner_kind([KIND_NAMES["human"], KIND_NAMES["human"]]) == "person"
    assert partner_kind([KIND_NAMES["avatar"]]) == "avatar"
    assert partner_kind(["recording", "recording"]) == "recording"
    assert partner_kind(["avatar", "person"]) == "mixed"
    assert partner_kind([]) == "none"
