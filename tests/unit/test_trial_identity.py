"""A trial's identity (its source, its BIDS entities), distinct labels, and sessions by start."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli.trial_sets import common_root, trial_identity
from mirror_avatar.files.bids.names import entities, folder_repeats_entities, recording_stem
from mirror_avatar.files.trials import make_trial
from mirror_avatar.metrics.progress import order_by_start, recorded_start
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.signature import distinct_labels


def test_entities_of_a_bids_name() -> None:
    name = "sub-01_ses-2_task-mirror_tracksys-leap_run-3_motion.tsv"
    assert entities(name) == {"sub": "01", "ses": "2", "task": "mirror", "tracksys": "leap",
                              "run": "3"}  # fmt: skip
    assert recording_stem(name) == "sub-01_ses-2_task-mirror_tracksys-leap_run-3"
    assert entities("trial_00.csv") == {} and entities("task-x_sub-01_motion.tsv") == {}
    assert recording_stem("trial_00.csv") == "trial_00"


@pytest.mark.parametrize(
    ("folder", "repeats"),
    [("sub-01", True), ("ses-2", True), ("motion", True), ("sub-02", False), ("p1", False)],
)
def test_bids_folders_that_repeat_the_name(folder: str, repeats: bool) -> None:
    assert folder_repeats_entities(folder, "sub-01_ses-2_task-x_run-1_motion.tsv") is repeats
    assert not folder_repeats_entities(folder, "trial_00.csv")


def test_identity_is_the_path_below_the_common_root(tmp_path: Path) -> None:
    for part in ("p1", "p2", "data/sub-01/ses-2/motion"):
        (tmp_path / part).mkdir(parents=True)
    root = common_root([tmp_path / "p1", tmp_path / "p2"])
    assert root == tmp_path
    assert trial_identity(tmp_path / "p1" / "trial_00.csv", root) == "p1/trial_00"
    assert trial_identity(tmp_path / "p2" / "trial_00.csv", root) == "p2/trial_00"
    bids = (
        tmp_path / "data" / "sub-01" / "ses-2" / "motion" / "sub-01_ses-2_task-x_run-4_motion.tsv"
    )
    assert trial_identity(bids, tmp_path) == "data/sub-01_ses-2_task-x_run-4"
    assert common_root([tmp_path / "p1" / "trial_00.csv"]) == tmp_path / "p1"
    assert trial_identity(Path("/elsewhere/a.csv"), tmp_path) == "a"


def test_repeated_labels_are_qualified_by_group_then_by_place() -> None:
    t = np.arange(30) / 10.0
    trials = [make_trial(t, 0.1 * np.sin(t), label=label, group=group)
              for label, group in (("trial_00", "p1"), ("trial_00", "p2"), ("x", "p1"),
                                   ("y", ""), ("y", ""))]  # fmt: skip
    assert distinct_labels(trials) == ["p1/trial_00", "p2/trial_00", "x", "y (1)", "y (2)"]


def session_with(metadata: dict) -> Session:
    times = np.arange(10) * 0.1
    values = np.zeros((2, 10))
    return Session(times, values, values, values, values, metadata=metadata)


def test_sessions_are_ordered_by_their_recorded_start() -> None:
    late = session_with({"started_utc": "2026-03-02T10:00:00+00:00",
                         "created_utc": "2026-03-01T09:00:00+00:00"})  # fmt: skip
    early = session_with({"created_utc": "2026-03-01T12:00:00"})
    lab = {"session_id": "s", "condition": "solo", "created_utc": "2026-03-01T08:00:00+00:00",
           "slots": [{"label": "P1", "kind": "human", "role": "solo"}]}  # fmt: skip
    lab_2 = session_with({"lab": lab | {"trial": 2}})
    lab_1 = session_with({"lab": lab | {"trial": 1}})
    assert recorded_start(late) == (datetime(2026, 3, 2, 10, tzinfo=UTC), 0)
    given = [("late", late), ("early", early), ("lab 2", lab_2), ("lab 1", lab_1)]
    ordered, untimed = order_by_start(given)
    assert [name for name, _ in ordered] == ["lab 1", "lab 2", "early", "late"] and not untimed
    unknown = session_with({"created_utc": "yesterday"})
    ordered, untimed = order_by_start([*given, ("unknown", unknown)])
    assert [name for name, _ in ordered] == ["late", "early", "lab 2", "lab 1", "unknown"]
    assert untimed == ["unknown"]
