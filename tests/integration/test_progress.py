"""A participant's progress across sessions: ``evaluate --progress``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mirror_avatar.cli import main
from mirror_avatar.metrics.progress import progress_table
from mirror_avatar.session import load_session
from mirror_avatar.signature import compute_emd, compute_ims


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


def test_evaluate_reports_progress(sessions: list[Path], tmp_path: Path, capsys) -> None:
    out = tmp_path / "report"
    assert main(["evaluate", *map(str, sessions), "--progress", "--out", str(out)]) == 0
    assert "progress of player 0 across the sessions" in capsys.readouterr().out
    metrics = json.loads((out / "metrics.json").read_text())
    names = [row["session"] for row in metrics["progress"]["progress"]]
    assert names == [f"session-{k}/session.parquet" for k in (1, 2, 3)]
    assert "Progress of player 0 across the sessions" in (out / "report.html").read_text()
