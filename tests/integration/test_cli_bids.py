"""BIDS datasets through the command line: runs and sessions stay apart, labels carry their
entities, an error writes nothing, and the toolkit reads its own lab export back."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.files.trial_io import read_csv_trial, write_csv_trial
from mirror_avatar.files.trials import Trial
from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.running.trial import LabTrial, build_avatars
from mirror_avatar.realtime.inputs import BrowserInput
from mirror_avatar.sessions.loading import load_session

CHANNELS = "name\tcomponent\ttype\tunits\nx\tx\tPOS\tmm\ny\ty\tPOS\tmm\n"


def write_runs(root: Path, subject: str, session: str, trials: list[Trial]) -> list[str]:
    """Runs 1..n of one subject's session, two position channels (x, y) in millimetres."""
    folder = root / f"sub-{subject}" / f"ses-{session}" / "motion"
    folder.mkdir(parents=True)
    stems = []
    for run, trial in enumerate(trials, start=1):
        stem = f"sub-{subject}_ses-{session}_task-mirror_tracksys-leap_run-{run}"
        rows = [f"{x * 600:.4f}\t0" for x in trial.resampled(100.0).positions]
        (folder / f"{stem}_motion.tsv").write_text("\n".join(rows) + "\n")
        sidecar = {"TaskName": "mirror", "SamplingFrequency": 100.0}
        (folder / f"{stem}_motion.json").write_text(json.dumps(sidecar))
        (folder / f"{stem}_channels.tsv").write_text(CHANNELS)
        stems.append(stem)
    return stems


@pytest.fixture
def dataset(zhai_trials, tmp_path) -> tuple[Path, list[str]]:
    """Two subjects, two sessions each, three runs per session."""
    root = tmp_path / "bids"
    stems = []
    for s, subject in enumerate(("01", "02")):
        for session in ("1", "2"):
            first = 9 * s + 3 * int(session) - 3
            stems += write_runs(root, subject, session, zhai_trials[first : first + 3])
    (root / "dataset_description.json").write_text('{"Name": "m", "BIDSVersion": "1.9.0"}')
    return root, stems


def test_convert_keeps_every_run_of_every_session(dataset, zhai_trials, tmp_path, capsys):
    root, stems = dataset
    out = tmp_path / "converted"
    arguments = ["convert", str(root), "--group-by", "bids", "--position-column", "x"]
    assert main([*arguments, "--position-unit", "mm", "--out", str(out)]) == 0
    assert "group 'sub-01': 6 trial(s)" in capsys.readouterr().out
    written = sorted(p.relative_to(out).as_posix() for p in out.rglob("*.csv"))
    assert written == sorted(f"sub-{stem[4:6]}/{stem}.csv" for stem in stems)
    back = read_csv_trial(out / "sub-02" / f"{stems[10]}.csv")
    np.testing.assert_allclose(
        back.positions, zhai_trials[13].resampled(100.0).positions, atol=1e-6
    )
    manifest = json.loads((out / "convert.json").read_text())
    assert [t["trial"] for t in manifest["trials"]] == stems


@pytest.mark.long
def test_signature_labels_carry_the_entities(dataset, tmp_path, capsys) -> None:
    root, stems = dataset
    out = tmp_path / "s"
    arguments = ["signature", str(root), "--group-by", "bids", "--position-column", "x"]
    assert main([*arguments, "--out", str(out)]) == 0
    result = json.loads((out / "signature.json").read_text())
    assert result["labels"] == stems
    assert "sub-01_ses-2_task-mirror_tracksys-leap_run-3" in result["labels"]
    assert "mirror" not in result["labels"]


def test_a_convert_that_fails_writes_nothing(zhai_trials, tmp_path, capsys) -> None:
    folder = tmp_path / "data" / "P01"
    folder.mkdir(parents=True)
    for k, name in enumerate(("a b.csv", "a_b.csv", "c.csv")):
        write_csv_trial(zhai_trials[k], folder / name)
    out = tmp_path / "converted"
    assert main(["convert", str(tmp_path / "data"), "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "a_b.csv" in error and "rename them" in error
    assert not out.exists()


def test_a_convert_into_a_folder_of_the_same_name_writes_nothing(
    zhai_trials, tmp_path, capsys
) -> None:
    (tmp_path / "data").mkdir()
    for k, name in enumerate(("a.csv", "b.csv")):
        write_csv_trial(zhai_trials[k], tmp_path / "data" / name)
    out = tmp_path / "converted"
    (out / "data" / "b.csv").mkdir(parents=True)
    assert main(["convert", str(tmp_path / "data"), "--out", str(out)]) == 2
    assert "is a folder" in capsys.readouterr().err
    assert not (out / "data" / "a.csv").exists()


RING = {
    "condition": "group",
    "graph": "ring",
    "duration": 10.0,
    "trials": 2,
    "players": [
        {"label": "P1", "kind": "human"},
        {"label": "A1", "kind": "avatar", "spec": "bundled:slow"},
        {"label": "P2", "kind": "human"},
    ],
}


@pytest.fixture
def exported(tmp_path: Path) -> Path:
    """A recorded ring session of two trials, exported by ``lab export``."""
    folder = tmp_path / "lab" / "20261125T010203-001"
    folder.mkdir(parents=True)
    plan = parse_plan(RING)
    avatars = build_avatars(plan)
    for n in (1, 2):
        inputs = {k: BrowserInput() for k in plan.humans}
        lab = {"session_id": folder.name, "condition": plan.condition}
        trial = LabTrial(plan, n, folder, inputs, avatars, time.monotonic, lab)
        while not trial.finished:
            for i, source in inputs.items():
                source.put(0.3 * math.sin(2 * math.pi * 0.3 * n * trial.k * 0.03 + i), trial.k)
            trial.tick()
        trial.finish(True, "completed")
    bids = tmp_path / "bids"
    assert main(["lab", "export", str(folder), "--out", str(bids)]) == 0
    return bids


def test_convert_reads_the_lab_export(exported: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "converted"
    assert main(["convert", str(exported), "--group-by", "bids", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "group 'sub-P1': 2 trial(s)" in printed and "group 'sub-P2': 2 trial(s)" in printed
    converted = sorted(out.rglob("*.csv"))
    assert [p.name for p in converted][:2] == [
        "sub-P1_task-mirrorgame_tracksys-pointer_acq-20261125T010203001_run-1.csv",
        "sub-P1_task-mirrorgame_tracksys-pointer_acq-20261125T010203001_run-2.csv",
    ]
    motion = sorted(exported.glob("sub-P2/motion/*run-2_motion.tsv"))[0]
    session = load_session(motion)
    trial = read_csv_trial(out / "sub-P2" / motion.name.replace("_motion.tsv", ".csv"))
    np.testing.assert_array_equal(trial.positions, session.positions[session.labels.index("P2")])
    assert session.metadata["bids"]["entities"]["run"] == "2"
