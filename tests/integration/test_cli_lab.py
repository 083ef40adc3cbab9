"""``mirror-avatar lab export``: a recorded lab session as BIDS-Motion, read back by the toolkit."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.running.trial import LabTrial, build_avatars
from mirror_avatar.realtime.inputs import BrowserInput
from mirror_avatar.sessions.loading import load_session

RING = {
    "condition": "group",
    "graph": "ring",
    "duration": 20.0,
    "trials": 2,
    "players": [
        {"label": "P1", "kind": "human"},
        {"label": "A1", "kind": "avatar", "spec": "bundled:slow"},
        {"label": "P_2", "kind": "human"},
        {"label": "A2", "kind": "avatar", "spec": "bundled:fast"},
    ],
}


@pytest.fixture(scope="module")
def lab_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A recorded ring session of two trials, as the lab server writes it."""
    folder = tmp_path_factory.mktemp("lab") / "20261124T010203-001"
    folder.mkdir()
    plan = parse_plan(RING)
    avatars = build_avatars(plan)
    for n in (1, 2):
        inputs = {k: BrowserInput() for k in plan.humans}
        lab = {"session_id": folder.name, "condition": plan.condition}
        trial = LabTrial(plan, n, folder, inputs, avatars, time.monotonic, lab)
        while not trial.finished:
            for i, source in inputs.items():
                source.put(
                    0.3 * math.sin(2 * math.pi * (0.4 + 0.1 * n) * trial.k * 0.03 + i), trial.k
                )
            trial.tick()
        trial.finish(True, "completed")
    return folder


@pytest.mark.long
def test_export_then_evaluate_and_signature_read_it(lab_session, tmp_path, capsys):
    bids = tmp_path / "bids"
    assert main(["lab", "export", str(lab_session), "--out", str(bids)]) == 0
    assert "wrote 4 motion files" in capsys.readouterr().out
    motion = sorted(bids.glob("sub-*/motion/*_motion.tsv"))
    assert [p.parent.parent.name for p in motion] == ["sub-P1", "sub-P1", "sub-P2", "sub-P2"]
    recorded = load_session(lab_session / "trial-02_session.csv")
    exported = load_session(motion[1])
    np.testing.assert_array_equal(exported.positions, recorded.positions)
    assert exported.labels == recorded.labels and exported.roles == recorded.roles
    assert main(["evaluate", str(motion[1]), "--out", str(tmp_path / "evaluated")]) == 0
    assert "group" in capsys.readouterr().out.lower()
    assert main(["signature", *map(str, motion[:2]), "--out", str(tmp_path / "signature")]) == 0


def test_export_of_a_folder_without_trials_is_one_line(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["lab", "export", str(tmp_path / "empty"), "--out", str(tmp_path / "b")]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "empty" in error


def bids_validated(bids: Path) -> dict:
    """The official BIDS validator's (its deno build) report on a dataset, after checking it
    found no error."""
    validator = Path(sys.executable).parent / "bids-validator-deno"
    report = subprocess.run(
        [validator, str(bids), "--format", "json"], capture_output=True, text=True, timeout=300
    )
    validated = json.loads(report.stdout)
    errors = [i for i in validated["issues"]["issues"] if i["severity"] == "error"]
    assert errors == [], errors[:3]
    return validated


def test_the_export_passes_the_bids_validator(lab_session, tmp_path):
    """The official BIDS validator (its deno build) finds no error in the exported dataset."""
    bids = tmp_path / "bids"
    assert main(["lab", "export", str(lab_session), "--out", str(bids)]) == 0
    report = bids_validated(bids)
    issues = report["issues"]["issues"]
    warnings = {issue["code"] for issue in issues}
    # only what a researcher adds (authors) or optional keys the game has no value for
    assert warnings <= {"NO_AUTHORS", "TOO_FEW_AUTHORS", "JSON_KEY_RECOMMENDED",
                        "SIDECAR_KEY_RECOMMENDED"}  # fmt: skip
    assert report["summary"]["dataTypes"] == ["motion"]
    (events,) = bids.glob("sub-P1/motion/*run-1_events.tsv")
    assert events.read_text().splitlines() == [
        "onset\tduration\ttrial_type\tsample\ttrial\tblock\tcondition\tplayer\tdelay_s\tchange",
        f"0.0\t{repr(668 * 0.03)}\ttrial\t0\t1\tn/a\tgroup\tn/a\tn/a\tn/a",
    ]
