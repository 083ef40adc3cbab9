"""BIDS-Motion datasets made by other tools, read by ``evaluate``: one player per tracked point
from a subject's ``_motion.tsv`` (POS channels, ``_channels.tsv`` units), a whole dataset or a
subject folder, never ``sourcedata/`` unless named. The dataset is written here by hand, per the
BIDS-Motion specification (``name``, ``component``, ``type``, ``tracked_point``, ``units``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.files.importing import PLAYING_RANGE_CM

RATE = 100.0
"""Sampling rate of the hand-made recording (Hz)."""


def hand_made(root: Path) -> tuple[np.ndarray, np.ndarray]:
    """Write a dataset: sub-01 tracks two hands (x, y, z in mm); return their x (mm)."""
    t = np.arange(1500) / RATE
    left = 80.0 * np.sin(2 * np.pi * 0.4 * t)
    right = 70.0 * np.sin(2 * np.pi * 0.4 * t - 0.3) + np.random.default_rng(1).normal(0, 2, t.size)
    folder = root / "sub-01" / "motion"
    folder.mkdir(parents=True)
    (root / "dataset_description.json").write_text(
        json.dumps({"Name": "hands", "BIDSVersion": "1.9.0"})
    )
    (root / "participants.tsv").write_text("participant_id\nsub-01\n")
    stem = "sub-01_task-mirror_tracksys-optical"
    rows = ["name\tcomponent\ttype\ttracked_point\tunits"]
    columns = []
    for point, x in (("leftHand", left), ("rightHand", right)):
        for component, values in (("x", x), ("y", 0.5 * x + 3), ("z", np.full_like(x, 900.0))):
            rows.append(f"{point}_{component}\t{component}\tPOS\t{point}\tmm")
            columns.append(values)
    rows.append("latency\tn/a\tLATENCY\tn/a\ts")
    columns.append(t)
    (folder / f"{stem}_channels.tsv").write_text("\n".join(rows) + "\n")
    np.savetxt(folder / f"{stem}_motion.tsv", np.column_stack(columns), delimiter="\t")
    sidecar = {"TaskName": "mirror", "SamplingFrequency": RATE, "TrackingSystemName": "optical",
               "MotionChannelCount": 7, "POSChannelCount": 6, "TrackedPointsCount": 2,
               "RecordingType": "continuous"}  # fmt: skip
    (folder / f"{stem}_motion.json").write_text(json.dumps(sidecar))
    (folder / f"{stem}_events.tsv").write_text("onset\tduration\ttrial_type\n0\t15\tgame\n")
    source = root / "sourcedata" / "raw"
    source.mkdir(parents=True)
    take = np.column_stack([t, 0.3 * np.sin(t), 0.3 * np.sin(t - 0.2)])
    np.savetxt(source / "take1.csv", take, delimiter=",", header="time,position_0,position_1",
               comments="")  # fmt: skip
    return left, right


def evaluated(paths: list[Path], capsys: pytest.CaptureFixture[str]) -> dict:
    capsys.readouterr()
    assert main(["evaluate", *map(str, paths), "--json", "--trim", "0", "--surrogates", "0"]) == 0
    out = capsys.readouterr().out
    return json.loads(out[out.index("{") :])


def test_evaluate_reads_each_tracked_point_as_a_player(tmp_path, capsys):
    left, right = hand_made(tmp_path / "ds")
    metrics = evaluated([tmp_path / "ds"], capsys)
    cm = 0.1  # mm
    expected = np.sqrt(np.mean(((left - right) * cm / PLAYING_RANGE_CM) ** 2))
    assert metrics["rmse"] == pytest.approx(expected, rel=1e-12)
    assert metrics["phase_locking"] > 0.95  # a constant lag, a little tracking noise
    assert metrics == evaluated([tmp_path / "ds" / "sub-01"], capsys)


def test_sourcedata_is_read_only_when_named(tmp_path, capsys):
    hand_made(tmp_path / "ds")
    capsys.readouterr()
    assert main(["evaluate", str(tmp_path / "ds"), "--surrogates", "0"]) == 0
    assert "take1" not in capsys.readouterr().out
    assert main(["evaluate", str(tmp_path / "ds" / "sourcedata"), "--surrogates", "0"]) == 0
    assert "rmse" in capsys.readouterr().out.lower()


def test_a_recording_without_positions_is_one_line(tmp_path, capsys):
    hand_made(tmp_path / "ds")
    channels = next((tmp_path / "ds").rglob("*_channels.tsv"))
    channels.write_text(channels.read_text().replace("\tPOS\t", "\tVEL\t"))
    motion = next((tmp_path / "ds").rglob("*_motion.tsv"))
    assert main(["evaluate", str(motion)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "no POS channel" in error
