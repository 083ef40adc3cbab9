"""A real two-player recording through the command line: named columns, irregular sampling.

Web pages and hand trackers stamp each frame as it comes: a ``time,human,avatar`` CSV at about
13 Hz with jittered steps is evaluated in one command and converted to a regular 100 Hz trial.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import PchipInterpolator

from mirror_avatar.cli import main
from mirror_avatar.files.trial_io import read_csv_trial

COLUMNS = "time=time,human=human,avatar=avatar"
FREQUENCY = 0.4
"""Hz of the two players' sinusoids."""
AVATAR_DELAY = 0.3
"""Seconds the avatar lags the human."""


def human(t: np.ndarray) -> np.ndarray:
    return 0.3 * np.sin(2 * np.pi * FREQUENCY * t)


def avatar(t: np.ndarray) -> np.ndarray:
    return human(t - AVATAR_DELAY)


def write_recording(path: Path, n: int = 300, seed: int = 7) -> np.ndarray:
    """Write a ``time,human,avatar`` CSV at an irregular ~13 Hz; return its times (s)."""
    rng = np.random.default_rng(seed)
    times = np.concatenate([[0.0], np.cumsum(rng.uniform(0.055, 0.1, n - 1))])
    path.parent.mkdir(parents=True, exist_ok=True)
    columns = (times.tolist(), human(times).tolist(), avatar(times).tolist())
    rows = [f"{t!r},{h!r},{a!r}" for t, h, a in zip(*columns, strict=True)]
    path.write_text("time,human,avatar\n" + "\n".join(rows) + "\n")
    return times


def run(capsys, *arguments: str) -> tuple[int, str, str]:
    status = main(list(arguments))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_recording_is_about_13_hz_and_irregular(tmp_path) -> None:
    steps = np.diff(write_recording(tmp_path / "trial.csv"))
    assert 12 < 1 / steps.mean() < 14 and steps.max() > 1.5 * steps.min()


def test_refusals_name_the_option_that_fixes_them(tmp_path, capsys) -> None:
    path = tmp_path / "trial.csv"
    write_recording(path)
    status, _, error = run(capsys, "evaluate", str(path), "--surrogates", "0")
    assert status == 2 and error.count("\n") == 1
    assert "'human'" in error and f"--columns {COLUMNS}" in error
    status, _, error = run(capsys, "evaluate", str(path), "--columns", COLUMNS, "--surrogates", "0")
    assert status == 2 and error.count("\n") == 1
    assert "irregular sampling" in error and "--resample HZ" in error


@pytest.mark.parametrize(
    ("value", "problem"),
    [("human=human", "time column first"), ("time=time", "at least one player"),
     ("time=time,human", "not KEY=COLUMN"), ("time=time,a=x,a=y", "label 'a' is given twice")],
)  # fmt: skip
def test_a_malformed_column_map_is_one_line(tmp_path, capsys, value, problem) -> None:
    path = tmp_path / "trial.csv"
    write_recording(path)
    status, _, error = run(capsys, "evaluate", str(path), "--columns", value)
    assert status == 2 and error.count("\n") == 1
    assert "--columns" in error and problem in error


def test_evaluated_in_one_command_with_the_players_labels(tmp_path, capsys) -> None:
    path = tmp_path / "trial.csv"
    write_recording(path)
    out = tmp_path / "report"
    status, text, error = run(
        capsys, "evaluate", str(path), "--columns", COLUMNS, "--resample", "100",
        "--surrogates", "0", "--out", str(out),
    )  # fmt: skip
    assert status == 0, error
    assert "player 0 human, player 1 avatar" in text
    read = next(line for line in text.splitlines() if "resampled from" in line)
    assert read.endswith("Hz (mean) to 100 Hz by PCHIP") and f"--columns {COLUMNS}" in read
    lag = next(line for line in text.splitlines() if line.startswith("time lag"))
    assert float(lag.split()[-2]) == pytest.approx(AVATAR_DELAY, abs=0.02)
    assert "player 0 human, player 1 avatar" in (out / "report.html").read_text()


def test_a_step_over_max_gap_is_refused_not_bridged(tmp_path, capsys) -> None:
    path = tmp_path / "trial.csv"
    times = write_recording(path)
    lines = path.read_text().splitlines()
    del lines[101:110]  # nine frames lost: a step of about 0.8 s
    path.write_text("\n".join(lines) + "\n")
    lost = times[109] - times[99]
    status, _, error = run(capsys, "evaluate", str(path), "--columns", COLUMNS, "--resample", "100")
    assert status == 2 and error.count("\n") == 1
    assert "--max-gap 0.2 s" in error and f"({lost:.3g} s)" in error
    status, _, error = run(
        capsys, "evaluate", str(path), "--columns", COLUMNS, "--resample", "100",
        "--max-gap", "1", "--surrogates", "0",
    )  # fmt: skip
    assert status == 0, error


def test_converted_to_regular_100_hz_trials(tmp_path, capsys) -> None:
    path = tmp_path / "lab" / "trial.csv"
    times = write_recording(path)
    out = tmp_path / "out"
    status, text, error = run(
        capsys, "convert", str(path), "--columns", COLUMNS, "--resample", "100", "--out", str(out)
    )
    assert status == 0, error
    assert "2 trial(s) resampled by PCHIP to 100 Hz from 12.9 Hz" in text
    assert "12.9->100" in text and "trial.csv (human)" in text
    assert text.splitlines()[-1] == (
        f"wrote 2 trial(s) to {out.resolve()}: lab/ (2); sources and options in convert.json"
    )
    for label, truth in (("human", human), ("avatar", avatar)):
        trial = read_csv_trial(out / "lab" / f"trial-{label}.csv")
        assert trial.is_uniform and trial.rate == pytest.approx(100.0)
        assert trial.times[0] == 0.0 and trial.times[-1] <= times[-1]
        expected = PchipInterpolator(times, truth(times))(np.arange(trial.n_samples) / 100.0)
        np.testing.assert_allclose(trial.positions, expected, rtol=0, atol=1e-12)
        assert np.max(np.abs(trial.positions - truth(trial.times))) < 5e-3
    manifest = json.loads((out / "convert.json").read_text())
    assert manifest["options"]["resample"] == 100.0
    files = [t["file"] for t in manifest["trials"]]
    assert files == ["lab/trial-human.csv", "lab/trial-avatar.csv"]


def test_a_hidden_source_folder_gives_a_visible_output_folder(tmp_path, capsys) -> None:
    write_recording(tmp_path / ".recordings" / "trial.csv")
    out = tmp_path / "out"
    status, text, error = run(
        capsys, "convert", str(tmp_path / ".recordings"), "--columns", COLUMNS,
        "--resample", "100", "--out", str(out),
    )  # fmt: skip
    assert status == 0, error
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*.csv")) == [
        "recordings/trial-avatar.csv",
        "recordings/trial-human.csv",
    ]
    assert f"to {out.resolve()}: recordings/ (2)" in text.splitlines()[-1]


def test_the_command_line_and_the_report_name_one_seed_and_no_nan(tmp_path, capsys) -> None:
    path = tmp_path / "trial.csv"
    write_recording(path)
    out = tmp_path / "report"
    status, text, error = run(
        capsys, "evaluate", str(path), "--columns", COLUMNS, "--resample", "100",
        "--surrogates", "19", "--surrogate-seed", "5", "--out", str(out),
    )  # fmt: skip
    assert status == 0, error
    assert "(19 shift surrogates, --surrogate-seed 5)" in text.splitlines()
    assert "No verdict on chance: 19 surrogates cannot give a p-value below 0.05" in text
    assert (
        "CV (phase locking, 0-1) against surrogates" in text and "p <= 0.05" in text
    )  # the players lock
    assert "p = 0.05" not in text and "nan" not in text.lower()
    report = (out / "report.html").read_text()
    assert "19 shift surrogates (--surrogate-seed 5:" in report
    assert "written p &lt;= 0.05" in report


@pytest.mark.parametrize("command", ["evaluate", "convert"])
@pytest.mark.parametrize(
    ("flag", "value"),
    [("--resample", "0"), ("--resample", "0.99"), ("--resample", "20000"), ("--resample", "nan"),
     ("--max-gap", "-1"), ("--max-gap", "inf")],
)  # fmt: skip
def test_reading_options_out_of_range_are_one_line(tmp_path, capsys, command, flag, value) -> None:
    path = tmp_path / "trial.csv"
    write_recording(path)
    out = ["--out", str(tmp_path / "out")] if command == "convert" else []
    status, _, error = run(capsys, command, str(path), "--columns", COLUMNS, flag, value, *out)
    assert status == 2 and error.count("\n") == 1 and flag in error
    assert not (tmp_path / "out").exists()
