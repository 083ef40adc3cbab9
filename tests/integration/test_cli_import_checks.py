"""Checks of recordings on import, through the command line: epoch clocks with blank cells,
the length of a drop-out, and what each trial looks like (rate, duration, range, centre)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.files.trial_io import read_csv_trial

RATE = 10.0
SAMPLES = 300
EPOCH_S = 1_764_000_000


def run(capsys: pytest.CaptureFixture[str], *arguments: str) -> tuple[int, str, str]:
    status = main(list(arguments))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def sway(n: int = SAMPLES, centre: float = 0.0, amplitude: float = 0.3) -> np.ndarray:
    """Positions (units) of a slow sine at 10 Hz."""
    return centre + amplitude * np.sin(2 * np.pi * 0.25 * np.arange(n) / RATE)


def write_clock(path: Path, clock: str, blank: tuple[int, ...] = (40, 41)) -> None:
    """A 10 Hz recording with Unix-epoch stamps (``epoch`` s or ``epoch_ms``), some cells blank."""
    lines = ["stamp,position"]
    for k, x in enumerate(sway()):
        if clock == "epoch":
            stamp = f"{EPOCH_S + k // 10}.{k % 10}"
        else:
            stamp = str(EPOCH_S * 1000 + 100 * k)
        lines.append(f"{stamp},{'' if k in blank else repr(float(x))}")
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("clock", ["epoch", "epoch_ms"])
def test_blank_cells_in_an_epoch_clock(clock: str, tmp_path: Path, capsys) -> None:
    """Two blank cells at 10 Hz leave 0.3 s between the positions around them: the message
    quotes that span, and --max-gap 0.3 interpolates it; times are exact multiples of 0.1 s."""
    source = tmp_path / "rec.csv"
    write_clock(source, clock)
    arguments = ["convert", str(source), "--time-column", "stamp", "--time-unit", clock]
    status, _, error = run(capsys, *arguments, "--out", str(tmp_path / "a"))
    assert status == 2 and error.count("\n") == 1
    found = re.search(r"between t = ([\d.]+) s and ([\d.]+) s \(([\d.]+) s of tracking lost", error)
    assert found is not None, error
    before, after, length = map(float, found.groups())
    assert (before, after, length) == (3.9, 4.2, 0.3)
    assert "2 sample(s) missing" in error and "--max-gap 0.2" in error
    assert not (tmp_path / "a").exists()
    status, out, error = run(capsys, *arguments, "--max-gap", "0.3", "--out", str(tmp_path / "b"))
    assert status == 0, error
    assert "2 missing sample(s) interpolated" in out
    trial = read_csv_trial(next((tmp_path / "b").rglob("rec.csv")))
    np.testing.assert_allclose(trial.times, np.arange(SAMPLES) / RATE, rtol=0, atol=1e-12)
    np.testing.assert_allclose(trial.positions[[40, 41]], np.interp([4.0, 4.1], [3.9, 4.2],
                               sway()[[39, 42]]), atol=1e-12)  # fmt: skip


LEAP_CLOCK_US = 5_812_345_678_901
"""A Leap Motion frame's timestamp: microseconds since its service started (67 days here)."""


@pytest.mark.parametrize(("unit", "first"), [("us", 0), ("epoch_us", LEAP_CLOCK_US)])
def test_microsecond_stamps_are_read_in_seconds(
    unit: str, first: int, tmp_path: Path, capsys
) -> None:
    """A time column in microseconds from 0 (``us``) or on Leap Motion's clock (``epoch_us``)."""
    source = tmp_path / "leap.csv"
    stamps = first + 100_000 * np.arange(SAMPLES)
    rows = (
        f"{stamp},{position!r}" for stamp, position in zip(stamps, sway().tolist(), strict=True)
    )
    source.write_text("\n".join(["timestamp,position", *rows]) + "\n")
    arguments = ["convert", str(source), "--time-column", "timestamp", "--time-unit", unit]
    status, _, error = run(capsys, *arguments, "--out", str(tmp_path / "out"))
    assert status == 0, error
    trial = read_csv_trial(next((tmp_path / "out").rglob("leap.csv")))
    np.testing.assert_allclose(trial.times, np.arange(SAMPLES) / RATE, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(trial.positions, sway())


def test_a_gap_just_over_the_limit_is_refused(tmp_path: Path, capsys) -> None:
    """Three blank cells (0.4 s between positions) are refused at --max-gap 0.3."""
    source = tmp_path / "rec.csv"
    write_clock(source, "epoch", blank=(40, 41, 42))
    status, _, error = run(capsys, "convert", str(source), "--time-column", "stamp",
                           "--time-unit", "epoch", "--max-gap", "0.3",
                           "--out", str(tmp_path / "a"))  # fmt: skip
    assert status == 2 and "(0.4 s of tracking lost, 3 sample(s) missing)" in error


def write_millimetres(path: Path, positions_mm: np.ndarray) -> None:
    """A 10 Hz recording in seconds and millimetres."""
    lines = ["time,x_mm"] + [f"{k / RATE!r},{x:.3f}" for k, x in enumerate(positions_mm)]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")


MM = ["--position-column", "x_mm", "--position-unit", "mm"]


def test_an_off_centre_tracker_is_reported_and_can_be_centred(tmp_path: Path, capsys) -> None:
    """A tracker reading 0-600 mm (its zero at one end) gives positions 0.07-0.91: the check
    table says so and warns; --centre and --offset 300 bring them back into the range."""
    wide = (sway(amplitude=0.42) + 0.49) * 600.0  # 0.07 to 0.91 units
    write_millimetres(tmp_path / "lab" / "off.csv", wide)
    write_millimetres(tmp_path / "lab" / "good.csv", sway() * 600.0)
    status, out, error = run(capsys, "convert", str(tmp_path / "lab"), *MM,
                             "--out", str(tmp_path / "a"))  # fmt: skip
    assert status == 0
    rows = {line.split()[0].rsplit("/", 1)[-1]: line for line in out.splitlines() if ".csv" in line}
    assert rows["off.csv"].split()[1:7] == ["10", "29.9", "0.07", "to", "0.91", "+0.49"]
    assert "outside [-0.5, 0.5]; off centre by +0.49" in rows["off.csv"]
    assert rows["good.csv"].endswith("none")
    assert "warning: 1 of 2 trial(s) have positions outside the playing range" in error
    assert "--centre or --offset" in error
    for option in (["--centre"], ["--offset", "300"]):
        out_dir = tmp_path / option[0].strip("-")
        status, out, error = run(capsys, "convert", str(tmp_path / "lab" / "off.csv"), *MM,
                                 *option, "--out", str(out_dir))  # fmt: skip
        assert status == 0 and error == "" and out.splitlines()[-2].endswith("none")
        trial = read_csv_trial(next(out_dir.rglob("off.csv")))
        expected = wide / 600.0 - (0.5 if option[0] == "--offset" else 0.49)
        np.testing.assert_allclose(trial.positions, expected, atol=1e-5)
        manifest = (out_dir / "convert.json").read_text()
        assert '"offset": 300.0' in manifest or '"centre": true' in manifest


def test_the_check_table_is_printed_wherever_trials_are_read(tmp_path: Path, capsys) -> None:
    write_millimetres(tmp_path / "p1" / "off.csv", (sway() + 0.4) * 600.0)
    write_millimetres(tmp_path / "p1" / "good.csv", sway(amplitude=0.2) * 600.0)
    status, out, error = run(capsys, "signature", str(tmp_path / "p1"), *MM,
                             "--out", str(tmp_path / "s"))  # fmt: skip
    assert status == 0
    assert "rate Hz" in out and "outside [-0.5, 0.5]" in out
    assert "have positions outside the playing range" in error


def test_a_replayed_recording_off_the_range_is_warned_of(tmp_path: Path, capsys) -> None:
    """A recording given as a player is clipped to the playing range: simulate says so."""
    write_millimetres(tmp_path / "off.csv", (sway() + 0.4) * 600.0)
    arguments = ["simulate", "--leader", str(tmp_path / "off.csv"), "--follower", "bundled:slow",
                 "--duration", "20", "--seed", "1", *MM]  # fmt: skip
    status, _, error = run(capsys, *arguments, "--out", str(tmp_path / "a"))
    assert status == 0
    assert "of the recording's positions lie outside the playing range [-0.5, 0.5]" in error
    assert "--centre or --offset" in error
    status, _, error = run(capsys, *arguments, "--centre", "--out", str(tmp_path / "b"))
    assert status == 0 and "warning" not in error
