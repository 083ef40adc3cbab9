"""A researcher's own files through the command line: columns, units, drop-outs, BIDS, folders."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.files.trial_io import read_csv_trial
from mirror_avatar.files.trials import Trial

LEAP = ["--time-column", "timestamp_ms", "--time-unit", "ms", "--position-column", "x_mm",
        "--position-unit", "mm"]  # fmt: skip


def write_leap(path: Path, trial: Trial, rate: float = 10.0, blank: slice | None = None) -> None:
    """A Leap-style recording: milliseconds, millimetres (60 cm = one unit), at ``rate`` Hz."""
    uniform = trial.resampled(rate)
    x_mm = uniform.positions * 600.0
    lines = ["timestamp_ms,x_mm,y_mm"]
    for k, (t, x) in enumerate(zip(uniform.times * 1000.0, x_mm, strict=True)):
        cell = "" if blank is not None and blank.start <= k < blank.stop else f"{x:.3f}"
        lines.append(f"{t:.1f},{cell},0.0")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")


def run(capsys, *arguments: str) -> tuple[int, str, str]:
    status = main(list(arguments))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_leap_millimetres_need_their_columns_and_units(zhai_trials, tmp_path, capsys) -> None:
    write_leap(tmp_path / "P01" / "leap.csv", zhai_trials[9])
    status, _, error = run(capsys, "signature", str(tmp_path / "P01"), "--out", str(tmp_path / "s"))
    assert status == 2 and error.count("\n") == 1
    assert "found ['timestamp_ms', 'x_mm', 'y_mm']" in error and "--position-column" in error
    status, out, _ = run(capsys, "convert", str(tmp_path / "P01"), "--out",
                         str(tmp_path / "converted"), *LEAP)  # fmt: skip
    assert status == 0 and "group 'P01': 1 trial(s) (leap)" in out
    converted = read_csv_trial(tmp_path / "converted" / "P01" / "leap.csv")
    original = zhai_trials[9].resampled(10.0)
    np.testing.assert_allclose(converted.times, original.times - original.times[0], atol=1e-9)
    np.testing.assert_allclose(converted.positions, original.positions, atol=1e-5)
    manifest = json.loads((tmp_path / "converted" / "convert.json").read_text())
    assert manifest["options"]["position_unit"] == "mm" and manifest["trials"][0]["group"] == "P01"


def test_millimetres_read_as_units_name_the_option(zhai_trials, tmp_path, capsys) -> None:
    write_leap(tmp_path / "leap.csv", zhai_trials[0])
    status, _, error = run(capsys, "generator", "fit", str(tmp_path / "leap.csv"), "--out",
                           str(tmp_path / "m.npz"), "--time-column", "timestamp_ms",
                           "--time-unit", "ms", "--position-column", "x_mm")  # fmt: skip
    assert status == 2 and "--position-unit mm, cm or m" in error


def test_epoch_time_stamps(zhai_trials, tmp_path, capsys) -> None:
    trial = zhai_trials[10].resampled(100.0)
    lines = ["time,position"] + [
        f"{1_700_000_000.0 + t:.3f},{float(x)!r}"
        for t, x in zip(trial.times, trial.positions, strict=True)
    ]
    (tmp_path / "epoch.csv").write_text("\n".join(lines) + "\n")
    arguments = ["generator", "fit", str(tmp_path / "epoch.csv"), "--out", str(tmp_path / "g.npz"),
                 "--kind", "ims", "--symbols", "32"]  # fmt: skip
    status, _, error = run(capsys, *arguments)
    assert status == 2 and "--time-unit epoch" in error
    status, _, _ = run(capsys, *arguments, "--time-unit", "epoch")
    assert status == 0 and (tmp_path / "g.npz").is_file()


def test_blank_cells_are_interpolated_up_to_the_limit(zhai_trials, tmp_path, capsys) -> None:
    write_leap(tmp_path / "short" / "gap.csv", zhai_trials[11], rate=100.0, blank=slice(60, 65))
    status, out, _ = run(capsys, "convert", str(tmp_path / "short"), "--out", str(tmp_path / "a"),
                         *LEAP)  # fmt: skip
    assert status == 0 and "5 missing sample(s) interpolated" in out
    trial = read_csv_trial(tmp_path / "a" / "short" / "gap.csv")
    assert np.all(np.isfinite(trial.positions)) and trial.n_samples == 100 * 60 + 1
    write_leap(tmp_path / "long" / "gap.csv", zhai_trials[11], rate=100.0, blank=slice(60, 110))
    status, _, error = run(capsys, "convert", str(tmp_path / "long" / "gap.csv"), "--out",
                           str(tmp_path / "b"), *LEAP)  # fmt: skip
    assert status == 2 and "tracking lost" in error and "--max-gap 0.2" in error
    status, _, _ = run(capsys, "convert", str(tmp_path / "long" / "gap.csv"), "--out",
                       str(tmp_path / "b"), *LEAP, "--max-gap", "1")  # fmt: skip
    assert status == 0


def write_bids_subject(root: Path, subject: str, trials: list[Trial]) -> None:
    """Two runs of one subject with three position channels (x, y, z) in millimetres."""
    folder = root / f"sub-{subject}" / "motion"
    folder.mkdir(parents=True)
    for run_index, trial in enumerate(trials, start=1):
        stem = f"sub-{subject}_task-mirror_tracksys-leap_run-{run_index}"
        uniform = trial.resampled(100.0)
        rows = [f"{x * 600:.4f}\t0\t0" for x in uniform.positions]
        (folder / f"{stem}_motion.tsv").write_text("\n".join(rows) + "\n")
        (folder / f"{stem}_motion.json").write_text(json.dumps({"SamplingFrequency": 100.0}))
        channels = "name\tcomponent\ttype\tunits\nx\tx\tPOS\tmm\ny\ty\tPOS\tmm\nz\tz\tPOS\tmm\n"
        (folder / f"{stem}_channels.tsv").write_text(channels)
    (root / "dataset_description.json").write_text(
        json.dumps({"Name": "mirror", "BIDSVersion": "1.9"})
    )


@pytest.mark.long
def test_a_bids_dataset_of_two_subjects(zhai_trials, tmp_path, capsys) -> None:
    root = tmp_path / "bids"
    write_bids_subject(root, "01", zhai_trials[0:2])
    write_bids_subject(root, "02", zhai_trials[9:11])
    out = str(tmp_path / "s")
    status, _, error = run(capsys, "signature", str(root), "--out", out)
    assert status == 2 and "3 channels (x, y, z)" in error and "--position-column" in error
    status, printed, _ = run(capsys, "signature", str(root), "--out", out,
                             "--position-column", "x", "--group-by", "bids")  # fmt: skip
    assert status == 0
    assert "group 'sub-01': 2 trial(s)" in printed and "group 'sub-02': 2 trial(s)" in printed
    assert json.loads((tmp_path / "s" / "signature.json").read_text())["group_names"] == [
        "sub-01",
        "sub-02",
    ]
    status, printed, _ = run(capsys, "signature", str(root), "--out", out, "--position-column", "x")
    assert "group 'sub-01/motion'" in printed and "group 'sub-02/motion'" in printed


def test_a_live_recording_folder(zhai_trials, tmp_path, capsys) -> None:
    """Solo trials beside a session file: the session is skipped with a note, then evaluated."""
    from mirror_avatar.live.messages import StartRequest
    from mirror_avatar.live.session import start_trial

    for index in (9, 10):
        trial = start_trial(tmp_path, StartRequest("solo", "P01", 20.0), None, None)
        for x in zhai_trials[index].resampled(1 / 0.03).positions[: trial.n_ticks]:
            trial.update_person(float(x), None)
            trial.tick()
        trial.finish(True, "completed")
    folder = tmp_path / "P01"
    status, printed, _ = run(capsys, "generator", "fit", str(folder), "--kind", "ims",
                             "--symbols", "32", "--out", str(tmp_path / "p01.npz"))  # fmt: skip
    assert status == 0 and printed.count("a session file (read it with evaluate)") == 2
    session = next(folder.glob("*_session.csv"))
    status, printed, _ = run(capsys, "evaluate", str(session))
    assert status == 0 and "EMD player 0 to its reference IMS" in printed


@pytest.mark.parametrize(
    ("arguments", "problem"),
    [
        (["--group-by", "sizes"], "unknown grouping"),
        (["--group-by", "pattern:("], "is not valid"),
        (["--group-by", "pattern:sub-(\\d+)"], "does not match"),
        (["--max-gap", "-1"], "--max-gap"),
    ],
)
def test_bad_import_options_are_one_line(zhai_trials, tmp_path, capsys, arguments, problem) -> None:
    write_leap(tmp_path / "P01" / "leap.csv", zhai_trials[9])
    status, _, error = run(capsys, "convert", str(tmp_path / "P01"), "--out", str(tmp_path / "o"),
                           *LEAP, *arguments)  # fmt: skip
    assert status == 2 and problem in error and error.count("\n") == 1


def test_a_recording_given_as_a_player_takes_the_import_options(zhai_trials, tmp_path, capsys):
    """simulate and train read a Leap file named as a SPEC with the same options."""
    leap = tmp_path / "leap.csv"
    write_leap(leap, zhai_trials[9], rate=50.0)
    arguments = ["simulate", "--leader", str(leap), "--follower", "bundled:slow", "--duration",
                 "20", "--seed", "1", "--out", str(tmp_path / "sim")]  # fmt: skip
    status, _, error = run(capsys, *arguments)
    assert status == 2 and "--position-column" in error
    status, out, _ = run(capsys, *arguments, *LEAP)
    assert status == 0 and "CV" in out
    replayed = json.loads((tmp_path / "sim" / "metrics.json").read_text())
    assert replayed["metrics"]["rmse"] < 0.2
    status, _, _ = run(capsys, "train", "--target", f"vt:{leap}", "--partners", "bundled:fast",
                       "--sessions", "2", "--duration", "5", "--jobs", "1", "--out",
                       str(tmp_path / "p.npz"), *LEAP)  # fmt: skip
    assert status == 0 and (tmp_path / "p.npz").is_file()
