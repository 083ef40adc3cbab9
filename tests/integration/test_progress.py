"""A participant's progress across sessions: ``evaluate --progress``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mirror_avatar.cli import main
from mirror_avatar.metrics.progress import progress_table
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.signatures.signature import compute_emd, compute_ims


@pytest.fixture(scope="module")
def sessions(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Player 0 moves slowly twice, then fast: its own motion drifts in the third session."""
    folder = tmp_path_factory.mktemp("progress")
    paths = []
    for k, (style, seed) in enumerate((("slow", 1), ("slow", 2), ("fast", 3)), start=1):
        out = folder / f"session-{k}"
        assert main(["simulate", "--leader", f"bundled:{style}", "--follower", "bundled:slow",
                     "--duration", "30", "--seed", str(seed), "--out", str(out)]) == 0  # fmt: skip
        paths.append(out / "session.parquet")
    return paths


def test_drift_is_measured_from_the_first_session(sessions: list[Path]) -> None:
    loaded = [(p.parent.name, load_session(p)) for p in sessions]
    table = progress_table(loaded, trim=1.0)
    assert list(table["session"]) == ["session-1", "session-2", "session-3"]
    drift = table["EMD to first session"]
    assert drift.iloc[0] == 0.0 and drift.iloc[1] < drift.iloc[2]
    first, third = (compute_ims(s.trimmed(1.0).velocities[0]) for _, s in (loaded[0], loaded[2]))
    assert drift.iloc[2] == pytest.approx(compute_emd(third, first))
    assert table["CV"].between(0, 1).all() and (table["RMS"] > 0).all()


@pytest.mark.long
def test_evaluate_reports_progress(sessions: list[Path], tmp_path: Path, capsys) -> None:
    out = tmp_path / "report"
    assert main(["evaluate", *map(str, sessions), "--progress", "--out", str(out)]) == 0
    assert "progress of player 0 across the sessions" in capsys.readouterr().out
    metrics = json.loads((out / "metrics.json").read_text())
    names = [row["session"] for row in metrics["progress"]["progress"]]
    assert names == [f"session-{k}/session.parquet" for k in (1, 2, 3)]
    page = (out / "report.html").read_text()
    assert "Progress of player 0 across the sessions" in page
    for k in (1, 2, 3):  # three files named session.parquet: each session keeps its figures
        assert f"session-{k}/session.parquet: positions" in page


@pytest.mark.long
def test_sessions_without_a_start_time_keep_the_order_given_and_say_so(
    sessions: list[Path], capsys
) -> None:
    assert main(["evaluate", *map(str, reversed(sessions)), "--progress"]) == 0
    printed = capsys.readouterr().out
    assert "(in the order given: 3 record no start time (session.parquet" in printed
    table = printed[printed.index("progress of player 0") :]
    assert table.index("session-3/") < table.index("session-1/")


def test_live_trials_are_followed_in_the_order_they_were_played(zhai_trials, tmp_path, capsys):
    """File names that sort against time: the start times the trials recorded decide."""
    from mirror_avatar.live.messages import StartRequest
    from mirror_avatar.live.session import start_trial

    created = []
    for k in range(3):
        trial = start_trial(tmp_path, StartRequest("solo", "P01", 10.0), None, None)
        for x in zhai_trials[9 + k].resampled(1 / 0.03).positions[: trial.n_ticks]:
            trial.update_person(float(x), None)
            trial.tick()
        trial.finish(True, "completed")
        (session,) = set((tmp_path / "P01").glob("*_session.csv")) - set(created)
        created.append(session)
    for k, session in enumerate(created):  # the first made was played last
        sidecar = session.with_suffix(".json")
        info = json.loads(sidecar.read_text())
        info["metadata"]["started_utc"] = f"2026-01-0{3 - k}T09:00:00+00:00"
        sidecar.write_text(json.dumps(info))
    assert main(["evaluate", str(tmp_path / "P01"), "--progress"]) == 0
    printed = capsys.readouterr().out
    assert "(ordered by the start time each recorded)" in printed
    table = printed[printed.index("progress of player 0") :].splitlines()[3:6]
    assert [line.split()[1] for line in table] == [p.name for p in reversed(created)]
