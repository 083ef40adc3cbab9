"""Tests of session files: every recording the toolkit writes reads back through load_session."""

import json
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.sessions.graphs import path_graph
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.sessions.session import Session
from mirror_avatar.sessions.writer import SessionWriter

CHANNELS = ("times", "positions", "velocities", "controls", "references")


def make_session(n_players: int, n: int = 50, seed: int = 0) -> Session:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.03
    x = 0.3 * np.sin(t[None] + rng.uniform(0, 3, (n_players, 1)))
    controls = rng.normal(size=(n_players, n))
    controls[:, -1] = np.nan
    references = np.full((n_players, n), np.nan)
    references[0, :-1] = 0.1
    graph = path_graph(n_players) if n_players > 1 else None
    return Session(t, x, np.cos(t) + 0 * x, controls, references, graph=graph,
                   metadata={"seed": seed})  # fmt: skip


def assert_same(a: Session, b: Session) -> None:
    for name in CHANNELS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    np.testing.assert_array_equal(a.graph, b.graph)
    assert a.labels == b.labels and a.roles == b.roles and a.metadata == b.metadata


@pytest.mark.parametrize("n_players", [1, 2, 3, 6])
@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_round_trip(tmp_path: Path, n_players: int, suffix: str) -> None:
    session = make_session(n_players)
    path = tmp_path / f"s{suffix}"
    (session.save if suffix == ".parquet" else session.save_csv)(path)
    back = load_session(path)
    assert_same(session, back)
    assert back.roles == {1: ("solo",), 2: ("leader", "follower")}.get(
        n_players, ("joint",) * n_players
    )
    sidecar = json.loads(path.with_suffix(".json").read_text())
    assert sidecar["n_players"] == n_players and sidecar["version"] == 2


def test_csv_columns_are_time_then_each_player_and_channel(tmp_path: Path) -> None:
    header = make_session(2).save_csv(tmp_path / "s.csv").read_text().splitlines()[0]
    assert header == (
        "time,position_0,velocity_0,control_0,reference_0,"
        "position_1,velocity_1,control_1,reference_1"
    )


def test_a_streamed_recording_reads_back_while_written_and_after_a_crash(tmp_path: Path) -> None:
    session = make_session(3)
    path = tmp_path / "live.csv"
    writer = SessionWriter(path, session.labels, session.roles, session.graph, 0.03, {"seed": 0})
    for row in session.table()[:20]:
        writer.append(row)
    partial = load_session(path)  # nothing closed yet
    assert partial.n_samples == 20 and partial.metadata["complete"] is False
    np.testing.assert_array_equal(partial.positions, session.positions[:, :20])
    with path.open("a") as file:  # a crash in the middle of a line
        file.write("0.6,0.1,0.2")
    assert load_session(path).n_samples == 20
    path.write_text(path.read_text() + "\n")
    with pytest.raises(InputError, match="line 22 holds 3 values where the first row holds 13"):
        load_session(path)  # a whole line with fields missing is damage, not a cut
    writer.close(True, {"metrics": {"rmse": 0.1}})


def test_closing_a_streamed_recording_completes_the_sidecar(tmp_path: Path) -> None:
    session = make_session(2)
    path = tmp_path / "live.csv"
    writer = SessionWriter(path, session.labels, session.roles, session.graph, 0.03, {})
    for row in session.table():
        writer.append(row)
    sidecar = writer.close(True, {"end_reason": "completed"})
    back = load_session(path)
    assert sidecar["n_samples"] == 50 and back.metadata["complete"] is True
    assert back.metadata["end_reason"] == "completed"
    assert_same(Session(**{n: getattr(session, n) for n in CHANNELS},
                        metadata=back.metadata), back)  # fmt: skip
    with pytest.raises(FileExistsError):
        SessionWriter(path, session.labels, session.roles, session.graph, 0.03, {})


def test_plain_position_files_get_velocities(tmp_path: Path) -> None:
    t = np.arange(0, 10, 0.01)
    x = np.stack([0.3 * np.sin(2 * np.pi * 0.5 * t), 0.2 * np.cos(2 * np.pi * 0.5 * t)])
    lines = ["time,position_0,position_1"] + [
        f"{a},{b},{c}" for a, b, c in zip(t, *x, strict=False)
    ]
    (tmp_path / "plain.csv").write_text("\n".join(lines) + "\n")
    session = load_session(tmp_path / "plain.csv")
    inner = slice(50, -50)
    expected = 0.3 * np.pi * np.cos(2 * np.pi * 0.5 * t)
    np.testing.assert_allclose(session.velocities[0, inner], expected[inner], atol=1e-3)
    assert np.all(np.isnan(session.controls)) and session.roles == ("leader", "follower")


def test_version_one_files_still_read(tmp_path: Path) -> None:
    """A two-player session written before graphs were recorded: the graph is complete."""
    session = make_session(2)
    path = session.save_csv(tmp_path / "old.csv")
    sidecar = json.loads(path.with_suffix(".json").read_text())
    for key in ("graph", "n_players"):
        del sidecar[key]
    sidecar["version"] = 1
    path.with_suffix(".json").write_text(json.dumps(sidecar))
    np.testing.assert_array_equal(load_session(path).graph, [[0, 1], [1, 0]])


def test_trimming() -> None:
    session = make_session(2)
    trimmed = session.trimmed(0.3)
    assert trimmed.times[0] == pytest.approx(0.3) and trimmed.n_samples == 40
    np.testing.assert_array_equal(trimmed.positions, session.positions[:, 10:])
    with pytest.raises(InputError, match="fewer than two"):
        session.trimmed(5.0)


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("time,position\n0,0\n0.1,0\n0.2,0\n", "no 'position_0' column"),
        ("t,position_0\n0,0\n", "no 'time' column"),
        ("time,position_0\n0,0\n0,0\n0.2,0\n", r"row 3: time repeats \(0 s after 0 s\)"),
        ("time,position_0\n0,0\n0.2,0\n0.1,0\n", r"row 4: time goes back \(0.1 s after 0.2 s\)"),
        ("time,position_0\n0,0\nn/a,0\n0.2,0\n", r"row 3: no time \(nan\)"),
        ("time,position_0,velocity_0,velocity_1,position_1\n0,0,0,0,0\n", "1 samples; a session"),
        ("time,position_0\n0,0\n0.1,0,5\n0.2,0\n", "line 3 holds 3 values where the first"),
        ("time,position_0\n0,0\n0.1\n0.2,0\n", "line 3 holds 1 value where the first"),
        ("time,position_0,position_1,velocity_0\n0,0,0,0\n0.1,0,0,0\n0.2,0,0,0\n", "velocity_1"),
        ("time,position_0\n0,a\n0.1,0\n0.2,0\n", "numeric"),
        ("time,position_0\n0,\n0.1,0\n0.2,0\n", "finite"),
    ],
)
def test_bad_session_files(tmp_path: Path, text: str, problem: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=problem) as error:
        load_session(path)
    assert str(error.value).startswith(str(path))


def test_missing_and_corrupt_files(tmp_path: Path) -> None:
    (tmp_path / "b.parquet").write_bytes(b"junk")
    with pytest.raises(InputError, match="Parquet"):
        load_session(tmp_path / "b.parquet")
    with pytest.raises(InputError, match="no such file"):
        load_session(tmp_path / "c.parquet")
    session = make_session(2)
    path = session.save_csv(tmp_path / "s.csv")
    path.with_suffix(".json").write_text("[1, 2]")
    with pytest.raises(InputError, match="not a JSON object"):
        load_session(path)
