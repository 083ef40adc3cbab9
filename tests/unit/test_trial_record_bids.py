"""The trial record carried from a lab trial's sidecar through its BIDS export and back.

The lab writes the record in the sidecar, the export copies it into every ``_motion.json``
through the record's one writer, and the study's readers get it back through its one reader,
equal field for field, from the run folder and from the export alike.
"""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mirror_avatar.analysis.trials import read_study_trials
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trial_record import (
    InputEventRecord,
    PageRecord,
    PerturbationRecord,
    SlotRecord,
    StudyRecord,
    TrialRecord,
    lab_trial_record,
    read_trial_record,
)
from mirror_avatar.lab.export.bids import export_bids
from mirror_avatar.sessions.graphs import complete_graph
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.sessions.writer import SessionWriter

T = 0.03
N_SAMPLES = 200

RECORD = TrialRecord(
    session_id="following-p003",
    trial=4,
    condition="joint",
    slots=(
        SlotRecord("P1", "human", "joint", None, "lsl", {"source_id": "hand", "invalid": 2}),
        SlotRecord("A1", "avatar", "joint", "ims:seed=3", None, runs="browser"),
        SlotRecord("P2", "human", "joint", None, "pointer"),
    ),
    study=StudyRecord(
        protocol="Following a hidden partner",
        participant=3,
        block="partners",
        condition="hidden",
        condition_trial=2,
        delay_s=0.3,
        occluded_s=((1.0, 2.5),),
        partners={"P1": "human", "A1": "avatar", "P2": "human"},
        panel={"P1": {"PROLIFIC_PID": "5f1a2b3c4d5e6f7a8b9c0d1e", "STUDY_ID": "s-42"}},
        consented={"P1": "2025-03-01T09:58:00+00:00", "P2": "2025-03-01T09:59:30+00:00"},
        partner_view={"handling": "equalised", "lag_s": 0.2, "horizon_s": None},
    ),
    seed=17,
    created_utc="2025-03-01T10:00:00+00:00",
    started_utc="2025-03-01T10:00:01.250000+00:00",
    complete=True,
    dropped={"P2": 150},
    perturbations=(PerturbationRecord(100, 3.0, "A1", "coupling 0.5"),),
    held={"P1": 4, "P2": 1},
    missing={"A1": 3},
    input_events=(InputEventRecord(120, "P1", "lost", 118), InputEventRecord(130, "P1", "live")),
    clock="local_clock",
    files={"session": "trial-04_session.csv", "inputs": "trial-04_inputs.csv"},
    pages={
        "P2": PageRecord(
            exchanges=98,
            rtt_ms={"n": 98, "mean": 171.0, "median": 168.5, "p95": 230.0, "max": 2100.0},
            offset_ms={"first": -3.5, "median": -1.0, "min": -4.0, "max": 2.5},
            uncertainty_ms={"first": 60.0, "median": 55.0, "min": 54.0, "max": 60.0},
            sample_rate_hz=240.5,
            frame_rate_hz=59.8,
            stalls=({"start_s": 12.25, "length_s": 2.0},),
            view={
                "frames": 512,
                "delay_ms": {"n": 512, "mean": 203.5, "median": 201.0, "p95": 219.0, "max": 260.0},
                "error_rms": 0.041,
            },
        )
    },
)
"""A record with every field of every part set (`test_the_record_sets_every_field`)."""


def write_run_folder(out: Path, record: TrialRecord) -> Path:
    """Record one trial of a study participant's run folder as the lab does."""
    assert record.study is not None
    folder = out / record.session_id
    folder.mkdir(parents=True)
    study = {"participant": record.study.participant, "protocol": {"source": "following.toml"}}
    (folder / "study.json").write_text(json.dumps(study))
    labels = [slot.label for slot in record.slots]
    roles = [slot.role for slot in record.slots]
    path = folder / f"trial-{record.trial:02d}_session.csv"
    writer = SessionWriter(path, labels, roles, complete_graph(len(labels)), T,
                           record.metadata_json())  # fmt: skip
    rng = np.random.default_rng(5)
    for time in np.arange(N_SAMPLES) * T:
        x = 0.3 * np.sin(time + np.arange(len(labels))) + 0.01 * rng.normal(size=len(labels))
        writer.append(np.array([time, *np.column_stack([x, np.cos(x), x, x]).ravel()]))
    writer.close(record.complete)
    return folder


def test_a_lab_trial_exported_to_bids_is_read_back_as_its_record(tmp_path: Path) -> None:
    folder = write_run_folder(tmp_path / "lab", RECORD)
    root = tmp_path / "bids"
    motions = export_bids(folder, root)
    assert read_trial_record(folder / "trial-04_session.json") == RECORD
    assert len(motions) == 2  # one recording per person, each carrying the record
    for motion in motions:
        assert lab_trial_record(load_session(motion).metadata) == RECORD
    [from_bids] = read_study_trials([root])
    [from_run] = read_study_trials([folder])
    assert from_bids.record == RECORD
    assert from_run.record == RECORD
    with (root / "participants.tsv").open(encoding="utf-8") as table:
        rows = {row["label"]: row for row in csv.DictReader(table, delimiter="\t")}
    assert (rows["P1"]["PROLIFIC_PID"], rows["P1"]["STUDY_ID"]) == (
        "5f1a2b3c4d5e6f7a8b9c0d1e",
        "s-42",
    )
    assert (rows["P2"]["PROLIFIC_PID"], rows["P2"]["STUDY_ID"]) == ("n/a", "n/a")


def test_an_export_by_an_earlier_version_is_read_as_far_as_it_carried_the_record(
    tmp_path: Path,
) -> None:
    """Version 1 of the ``MirrorGame`` key kept the ``lab`` object's keys at its top, no study."""
    root = tmp_path / "bids"
    [motion, _] = export_bids(write_run_folder(tmp_path / "lab", RECORD), root)
    sidecar = motion.with_name(motion.name.replace(".tsv", ".json"))
    info = json.loads(sidecar.read_text())
    game = info["MirrorGame"]
    info["MirrorGame"] = {"format": game["format"], "version": 1, "session_id": RECORD.session_id,
                          "trial": RECORD.trial, "condition": RECORD.condition,
                          "created_utc": RECORD.created_utc, "started_utc": RECORD.started_utc,
                          "clock": RECORD.clock, "participant": "P1", "slot": 0,
                          "slots": [slot.to_json() for slot in RECORD.slots],
                          "graph": game["graph"], "start_time": game["start_time"],
                          "complete": True, "dropped": RECORD.dropped, "held": RECORD.held,
                          "seed": RECORD.seed}  # fmt: skip
    sidecar.write_text(json.dumps(info))
    carried = dataclasses.replace(
        RECORD, study=None, perturbations=(), input_events=(), files={}, missing={}, pages={}
    )
    assert lab_trial_record(load_session(motion).metadata) == carried
    with pytest.raises(InputError, match="carries no study record.*sourcedata/following-p003/"):
        read_study_trials([root / "sub-p003P1"])


def test_a_sidecar_of_a_newer_format_is_refused_in_one_line_naming_it(tmp_path: Path) -> None:
    folder = write_run_folder(tmp_path / "lab", RECORD)
    sidecar = folder / "trial-04_session.json"
    info = json.loads(sidecar.read_text())
    sidecar.write_text(json.dumps(info | {"version": 99}))
    with pytest.raises(InputError, match=r"trial-04_session\.json: version 99: .*newer") as refused:
        read_study_trials([folder])
    assert "\n" not in str(refused.value)
    sidecar.write_text(json.dumps(info | {"version": "2"}))
    with pytest.raises(InputError, match="version '2' is not a whole number"):
        load_session(folder / "trial-04_session.csv")


def test_an_export_of_a_newer_format_is_refused_in_one_line_naming_it(tmp_path: Path) -> None:
    root = tmp_path / "bids"
    [motion, _] = export_bids(write_run_folder(tmp_path / "lab", RECORD), root)
    sidecar = motion.with_name(motion.name.replace(".tsv", ".json"))
    info = json.loads(sidecar.read_text())
    info["MirrorGame"]["version"] = 99
    sidecar.write_text(json.dumps(info))
    with pytest.raises(InputError, match=f"{sidecar.name}: MirrorGame.version 99: .*newer"):
        read_study_trials([root])


def test_a_record_kept_without_its_recording_is_refused_not_left_out(tmp_path: Path) -> None:
    folder = write_run_folder(tmp_path / "lab", RECORD)
    (folder / "trial-04_session.csv").unlink()
    with pytest.raises(InputError, match=r"trial-04_session\.csv: missing, but its record"):
        read_study_trials([folder])


def test_the_record_sets_every_field() -> None:
    """A field added to the record is set here, so an export that misses it fails above."""
    assert _left_at_default(RECORD) == set()


def _left_at_default(record: Any) -> set[str]:
    """Name the fields of the record's parts that no part of their kind sets (version aside)."""
    set_somewhere: dict[str, bool] = {}

    def walk(part: Any) -> None:
        for field in dataclasses.fields(part):
            value = getattr(part, field.name)
            name = f"{type(part).__name__}.{field.name}"
            set_somewhere[name] = set_somewhere.get(name, False) or value != _default(field)
            for each in value if isinstance(value, tuple) else (value,):
                if dataclasses.is_dataclass(each):
                    walk(each)

    walk(record)
    return {name for name, is_set in set_somewhere.items() if not is_set} - {"TrialRecord.version"}


def _default(field: dataclasses.Field[Any]) -> object:
    """Return a field's default value (a marker nothing equals when it has none)."""
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    return dataclasses.MISSING
