"""``evaluate``'s bounds through the real command line: every option's declared range, the
magnitudes a session may hold, high-rate sessions at the analysis rate, and outputs written as a
set.

The refusal tests are generated from the declarations (`mirror_avatar.metrics.measures.CONSTRAINTS`
and ``--trim``'s): every value a declaration names as refused must be refused in one line naming
the option, with exit code 2, before any session is read.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.cli.constrained import TRIM_RANGE
from mirror_avatar.cli.measure_options import OPTIONS
from mirror_avatar.common.constraints import Constraint, Options
from mirror_avatar.metrics.analysis_rate import ANALYSIS_RATE
from mirror_avatar.metrics.measures import CONSTRAINTS
from mirror_avatar.testing import smooth_motion

DECLARED = [("--trim", TRIM_RANGE)] + [(flag, CONSTRAINTS[name]) for name, flag, _ in OPTIONS]
"""Every option of ``evaluate`` with a declared range."""


def allowed_ends(constraint: Constraint) -> list[str]:
    """The most extreme values a declaration allows (its words, for options)."""
    if isinstance(constraint, Options):
        return list(constraint.values)
    ends = []
    for end, inward, closed in (
        (constraint.low, 1.0, constraint.closed in ("both", "left")),
        (constraint.high, -1.0, constraint.closed in ("both", "right")),
    ):
        if end is None:
            ends.append(str(constraint.kind(-inward * 1e300)) if constraint.kind is float else "")
        elif closed:
            ends.append(str(constraint.kind(end)))
        else:
            ends.append(repr(math.nextafter(end, end + inward)))
    return [end for end in ends if end]


EXTREMES = [
    pytest.param(flag, value, id=f"{flag}={value}")
    for flag, constraint in DECLARED
    for value in allowed_ends(constraint)
    if (flag, value) != ("--surrogates", "9999")  # minutes of work: the unit tests check it
]

REFUSALS = [
    pytest.param(flag, value, id=f"{flag}={value}")
    for flag, constraint in DECLARED
    for value in constraint.refused()
]


def write_pair(path: Path, rate: float, seconds: float, seed: int = 0) -> None:
    """A pair in which player 1 repeats player 0's motion 0.2 s later."""
    n, delay = round(seconds * rate), round(0.2 * rate)
    s = 0.3 * smooth_motion(np.random.default_rng(seed), n + delay, rate) / 0.1
    table = np.column_stack([np.arange(n) / rate, s[delay:], s[:n]])
    np.savetxt(path, table, fmt="%.6f", delimiter=",", header="time,position_0,position_1",
               comments="")  # fmt: skip


def evaluate(capsys: pytest.CaptureFixture[str], *arguments: str) -> tuple[int, str, str]:
    capsys.readouterr()
    status = main(["evaluate", *arguments])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.mark.long
def test_every_option_declares_its_range_in_its_help():
    help_text = subprocess.run(
        [sys.executable, "-c", "from mirror_avatar.console import run; run()", "evaluate", "-h"],
        capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    flat = " ".join(help_text.split())
    for flag, constraint in DECLARED:
        assert flag in flat and f"Allowed: {constraint}" in flat, flag


@pytest.mark.parametrize(("flag", "value"), REFUSALS)
def test_a_value_outside_an_options_declared_range_is_refused_in_one_line(
    tmp_path, capsys, flag, value
):
    missing = tmp_path / "not-read.csv"  # refused before any session is read
    status, printed, error = evaluate(capsys, str(missing), flag, str(value))
    assert status == 2 and printed == ""
    assert len(error.strip().splitlines()) == 1 and flag in error, error


@pytest.mark.parametrize(("flag", "value"), EXTREMES)
def test_the_ends_of_every_range_give_results_or_one_line(tmp_path, capsys, flag, value):
    pair = tmp_path / "pair.csv"
    write_pair(pair, 50.0, 20.0)
    status, _, error = evaluate(capsys, str(pair), "--surrogates", "2", flag, value)
    assert status in (0, 2), error
    assert status == 0 or (len(error.strip().splitlines()) == 1 and "error:" in error), error


@pytest.mark.parametrize(
    "arguments",
    [
        ["--lead-max-lag", "-1"],
        ["--te-bins", "1000000"],
        ["--sync-window", "1e9"],
        ["--trim", "nan"],
        ["--trim", "-5"],
        ["--leader-share", "nan"],
        ["--jitter-threshold", "nan"],
        ["--lead-window", "1e9"],
        ["--surrogates", "1000000000"],
        ["--te-bins", "64", "--te-history", "4"],
        ["--lead-max-lag", "0.001"],
    ],
    ids=" ".join,
)
def test_the_reported_values_are_refused_in_one_line(tmp_path, capsys, arguments):
    pair = tmp_path / "pair.csv"
    write_pair(pair, 50.0, 20.0)
    status, _, error = evaluate(capsys, str(pair), "--surrogates", "2", *arguments)
    assert status == 2 and len(error.strip().splitlines()) == 1, error
    assert arguments[0].removeprefix("--").replace("-", "_") in error.replace("-", "_")


def test_positions_too_large_for_the_measures_are_refused_naming_the_file(tmp_path, capsys):
    pair = tmp_path / "huge.csv"
    write_pair(pair, 50.0, 20.0)
    lines = pair.read_text().splitlines()
    lines[100] = "1.980000,1e308,0.1"
    pair.write_text("\n".join(lines) + "\n")
    status, _, error = evaluate(capsys, str(pair), "--surrogates", "2")
    assert status == 2 and len(error.strip().splitlines()) == 1
    assert f"{pair}: positions reach 1e+308" in error


def test_a_trim_longer_than_a_session_is_refused_naming_the_file(tmp_path, capsys):
    pair = tmp_path / "pair.csv"
    write_pair(pair, 50.0, 20.0)
    status, _, error = evaluate(capsys, str(pair), "--trim", "1e9")
    assert status == 2
    assert error.strip() == (
        f"mirror-avatar: error: {pair}: --trim 1e+09 s leaves fewer than two samples of its 19.98 s"
    )


@pytest.mark.parametrize(("resample", "refused"), [("1", True), ("6", True), ("7", False)])
def test_a_rate_too_slow_for_the_jitter_band_names_the_resample_option(
    tmp_path, capsys, resample, refused
):
    pair = tmp_path / "pair.csv"
    write_pair(pair, 50.0, 20.0)
    status, _, error = evaluate(capsys, str(pair), "--surrogates", "0", "--resample", resample)
    if refused:
        assert status == 2 and error.strip() == (
            f"mirror-avatar: error: {pair}: --resample {resample} Hz is too slow: the measures "
            "need more than 6 Hz (the jitter band, 2-3 Hz)"
        )
    else:
        assert status == 0, error


def test_a_slow_recording_is_refused_as_unmeasurable(tmp_path, capsys):
    pair = tmp_path / "pair.csv"
    write_pair(pair, 5.0, 60.0)
    status, _, error = evaluate(capsys, str(pair), "--surrogates", "0")
    assert status == 2
    assert f"{pair}: sampled at 5 Hz: the measures need more than 6 Hz" in error


def test_a_folder_whose_every_file_is_refused_says_why(tmp_path, capsys):
    folder = tmp_path / "sessions"
    folder.mkdir()
    write_pair(folder / "back.csv", 50.0, 20.0)
    lines = (folder / "back.csv").read_text().splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    (folder / "back.csv").write_text("\n".join(lines) + "\n")
    (folder / "ragged.csv").write_text("time,position_0,position_1\n0,0.1,0.2\n0.02,0.1\n")
    status, _, error = evaluate(capsys, str(folder))
    assert status == 2 and len(error.strip().splitlines()) == 1
    assert (
        f"{folder}: no session read: its 2 files were refused (back.csv: row 7: time goes back"
        in error
    )
    assert "ragged.csv: line 3 holds 2 values where the first row holds 3" in error


def test_a_session_too_short_for_leadership_says_so(tmp_path, capsys):
    pair = tmp_path / "short.csv"
    write_pair(pair, 50.0, 8.0)
    status, printed, _ = evaluate(capsys, str(pair), "--surrogates", "0", "--lead-window", "10")
    assert status == 0
    assert f"{pair}: no leadership: 6.98 s is shorter than --lead-window + 2 --lead-max-lag" in (
        printed
    )


def test_a_high_rate_pair_is_analysed_at_the_analysis_rate_with_the_same_numbers(tmp_path, capsys):
    fast, slow = tmp_path / "fast.csv", tmp_path / "slow.csv"
    write_pair(fast, 1000.0, 60.0)
    table = np.loadtxt(fast, delimiter=",", skiprows=1)[::10]
    np.savetxt(slow, table, fmt="%.6f", delimiter=",", header="time,position_0,position_1",
               comments="")  # fmt: skip
    status, printed, _ = evaluate(capsys, str(fast), "--surrogates", "19", "--json")
    note, _, text = printed.partition("\n")
    assert status == 0 and note == (
        f"{fast}: sampled at 1000 Hz, analysed at {ANALYSIS_RATE:g} Hz (every 10th sample after "
        "an anti-aliasing filter; the measures need at most 100 Hz)"
    )
    a = json.loads(text)
    status, printed, _ = evaluate(capsys, str(slow), "--surrogates", "19", "--json")
    assert status == 0
    b = json.loads(printed)
    for key in ("phase_locking", "rmse", "mean_relative_phase", "leader_share"):
        assert a[key] == pytest.approx(b[key], abs=2e-3), key
    assert a["time_lag"] == b["time_lag"] == pytest.approx(0.2)
    assert a["leader"] == b["leader"] == 0 and a["leader_lag_s"] == b["leader_lag_s"]
    for key in ("transfer_entropy_0_to_1", "transfer_entropy_1_to_0"):
        assert a[key] == pytest.approx(b[key], rel=0.05), key
    assert a["phase_locking_p_value"] == b["phase_locking_p_value"] == pytest.approx(0.05)


FILE_SIZE_LIMIT = 200_000
"""Bytes a file may grow to in the child below: more than the table and the metrics of a short
pair, less than its report with figures."""

LIMITED = f"""
import resource
resource.setrlimit(resource.RLIMIT_FSIZE, ({FILE_SIZE_LIMIT}, {FILE_SIZE_LIMIT}))
from mirror_avatar.console import run
run()
"""
"""Child: the command line under a file-size limit (a write beyond it fails with EFBIG: Python
ignores SIGXFSZ)."""


@pytest.mark.long
def test_a_report_that_cannot_be_written_leaves_no_other_output(tmp_path):
    pair, out = tmp_path / "pair.csv", tmp_path / "out"
    write_pair(pair, 50.0, 30.0)
    command = [sys.executable, "-c", LIMITED, "evaluate", str(pair), "--surrogates", "9",
               "--out", str(out)]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, check=False, timeout=600)
    assert done.returncode == 2 and "File too large" in done.stderr, done.stderr
    assert not out.exists() or sorted(p.name for p in out.iterdir()) == []
