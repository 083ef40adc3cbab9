"""``mirror-avatar simulate`` and ``evaluate`` through the command line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from console_child import run_console
from mirror_avatar.cli import main
from mirror_avatar.files.trial_files import write_trial
from mirror_avatar.files.trials import Trial
from mirror_avatar.metrics import session_metrics
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.specs import bundled_generator


@pytest.fixture(autouse=True)
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Fitted bundled generators go to a per-test cache."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    bundled_generator.cache_clear()


def _simulate(out: Path, *extra: str) -> int:
    arguments = ["simulate", "--duration", "20", "--out", str(out), *extra]
    return main(arguments)


def test_simulate_writes_session_and_metrics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    status = _simulate(out, "--leader", "bundled:slow", "--follower", "bundled:fast", "--seed", "7")
    printed = capsys.readouterr().out
    assert status == 0
    assert str(out.resolve()) in printed and "CV" in printed
    summary = json.loads((out / "metrics.json").read_text())
    assert summary["seed"] == 7
    assert summary["specs"] == {"player 0": "bundled:slow", "player 1": "bundled:fast"}
    assert summary["roles"] == ["leader", "follower"]
    parquet = load_session(out / "session.parquet")
    csv = load_session(out / "session.csv")
    np.testing.assert_allclose(csv.positions, parquet.positions, rtol=1e-12)
    assert parquet.times.size == round(20 / 0.03) + 1
    assert parquet.metadata["specs"] == ["bundled:slow", "bundled:fast"]
    recomputed = session_metrics(parquet, trim=summary["trim"])
    assert recomputed == pytest.approx(summary["metrics"])
    assert summary["metrics"]["emd_reference_0"] < summary["metrics"]["emd_reference_1"]

    assert main(["evaluate", str(out / "session.parquet"), "--json", "--surrogates", "0"]) == 0
    evaluated = json.loads(capsys.readouterr().out)
    assert {k: evaluated[k] for k in summary["metrics"]} == pytest.approx(summary["metrics"])
    assert "co_confidence_rate" in evaluated  # and the field's measures beside them
    assert main(["evaluate", str(out / "session.csv")]) == 0
    table = capsys.readouterr().out
    cv = summary["metrics"]["phase_locking"]
    assert f"{cv:.4f}" in table.splitlines()[0]


def test_same_seed_same_session(tmp_path: Path) -> None:
    specs = ["--leader", "bundled:slow", "--follower", "bundled:slow", "--seed", "3"]
    assert _simulate(tmp_path / "a", *specs) == 0
    assert _simulate(tmp_path / "b", *specs) == 0
    a = load_session(tmp_path / "a" / "session.parquet")
    b = load_session(tmp_path / "b" / "session.parquet")
    np.testing.assert_array_equal(a.positions, b.positions)


def test_recorded_leader_and_joint_roles(tmp_path: Path, zhai_trials: list[Trial]) -> None:
    person = tmp_path / "person.csv"
    write_trial(zhai_trials[12], person)
    out = tmp_path / "run"
    status = _simulate(out, "--leader", str(person), "--follower", f"vt:{person}", "--joint")
    assert status == 0
    session = load_session(out / "session.parquet")
    assert session.roles == ("joint", "joint")
    assert session.metadata["players"][0]["class"] == "RecordedPlayer"
    assert np.all(np.isnan(session.references[0]))
    summary = json.loads((out / "metrics.json").read_text())
    assert summary["metrics"]["emd_reference_0"] is None
    assert isinstance(summary["seed"], int)


def test_a_recording_shorter_than_the_session_is_refused_unless_extended(
    tmp_path: Path, zhai_trials: list[Trial], capsys: pytest.CaptureFixture[str]
) -> None:
    person = tmp_path / "person.csv"
    write_trial(zhai_trials[12], person)  # 60 s
    arguments = ["simulate", "--leader", str(person), "--follower", "bundled:slow", "--duration",
                 "90", "--out", str(tmp_path / "run")]  # fmt: skip
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert "the recording lasts 60 s (12.97 Hz), the session 90 s" in error
    assert "--extend-recordings" in error
    assert not (tmp_path / "run").exists()
    assert main([*arguments, "--extend-recordings"]) == 0
    session = load_session(tmp_path / "run" / "session.parquet")
    assert np.ptp(session.positions[0, session.times > 61]) == 0  # the leader holds still


@pytest.mark.parametrize("spec", ["{}", "vt:{}"])
def test_a_recording_short_by_one_sampling_interval_is_its_full_length(
    spec: str, tmp_path: Path, zhai_trials: list[Trial], capsys: pytest.CaptureFixture[str]
) -> None:
    """600 samples at 10 Hz span 59.9 s and make a 60 s recording; 598 (59.7 s) are short."""
    uniform = zhai_trials[12].resampled(10.0)
    for n, status in ((600, 0), (598, 2)):
        person = tmp_path / f"person{n}.csv"
        write_trial(Trial(uniform.times[:n], uniform.positions[:n]), person)
        out = tmp_path / f"run{n}"
        arguments = ["simulate", "--leader", spec.format(person), "--follower", "bundled:slow",
                     "--seed", "1", "--out", str(out)]  # fmt: skip
        assert main(arguments) == status, capsys.readouterr().err
        error = capsys.readouterr().err
        assert ("the recording lasts 59.7 s (10 Hz), the session 60 s" in error) == bool(status)
        assert (out / "session.parquet").exists() != bool(status)


@pytest.mark.parametrize(
    ("arguments", "source"),
    [
        (["--leader", "nobody", "--follower", "bundled:slow"], "nobody"),
        (["--leader", "bundled:slow", "--follower", "bundled:medium"], "bundled:medium"),
        (["--leader", "bundled:slow", "--follower", "bundled:slow", "--trim", "60"], "--trim"),
        (
            ["--leader", "bundled:slow", "--follower", "bundled:slow", "--duration", "0"],
            "Invalid value for '--duration'",
        ),
    ],
)
def test_simulate_bad_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], arguments: list[str], source: str
) -> None:
    status = main(["simulate", "--out", str(tmp_path / "out"), *arguments])
    error = capsys.readouterr().err
    assert status == 2
    assert error.startswith(f"mirror-avatar: error: {source}") and error.count("\n") == 1


def test_bad_input_through_the_console_script(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    runs = [
        ["evaluate", str(tmp_path / "missing.parquet")],
        ["evaluate", str(blocker)],
        ["simulate", "--leader", "bundled:slow", "--follower", "x.npz", "--out", str(blocker)],
    ]
    for arguments in runs:
        result = run_console(arguments, tmp_path, timeout=300)
        assert result.returncode == 2, result.stderr
        assert result.stderr.startswith("mirror-avatar: error: ")
        assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr


def test_simulate_draws_the_session(tmp_path: Path) -> None:
    out = tmp_path / "drawn"
    assert (
        _simulate(out, "--leader", "bundled:fast", "--follower", "bundled:slow", "--seed", "2") == 0
    )
    for name in ("positions.png", "relative_phase.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG"


@pytest.mark.long
def test_evaluate_a_folder_of_sessions(
    tmp_path: Path, zhai_trials: list[Trial], capsys: pytest.CaptureFixture[str]
) -> None:
    """Simulations and a plain two-player file in one folder: one table, solo trials skipped."""
    folder = tmp_path / "study"
    _simulate(folder / "a", "--leader", "bundled:fast", "--follower", "bundled:slow", "--seed", "1")
    (folder / "solo").mkdir()
    write_trial(zhai_trials[3], folder / "solo" / "person.csv")
    t = np.arange(0, 20, 0.01)
    lines = ["time,position_0,position_1"] + [
        f"{a},{0.3 * np.sin(a)},{0.3 * np.sin(a - 0.3)}" for a in t
    ]
    (folder / "plain.csv").write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    assert main(["evaluate", str(folder), "--out", str(tmp_path / "table")]) == 0
    printed = capsys.readouterr().out
    assert "skipped" in printed and "person.csv" in printed and "same session" in printed
    table = (tmp_path / "table" / "sessions.csv").read_text().splitlines()
    assert len(table) == 3 and table[0].startswith("session,players,seconds,phase_locking")
    # positions and relative phase, then timeline, leadership and surrogates, for each pair
    assert (tmp_path / "table" / "report.html").read_text().count("<img") == 10
    metrics = json.loads((tmp_path / "table" / "metrics.json").read_text())["sessions"]
    plain = metrics[str(folder / "plain.csv")]
    assert plain["mean_relative_phase"] == pytest.approx(0.3, abs=0.02)
