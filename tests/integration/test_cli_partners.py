"""The partners from the literature as player specs of ``simulate``, ``group`` and ``train``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mirror_avatar.cli import main
from mirror_avatar.sessions.loading import load_session


def test_simulate_a_leader_with_the_adaptive_follower(tmp_path: Path) -> None:
    out = tmp_path / "dyad"
    status = main(["simulate", "--leader", "hkb:omega=2", "--follower", "adaptive:cp=50",
                   "--duration", "10", "--seed", "3", "--out", str(out)])  # fmt: skip
    assert status == 0
    summary = json.loads((out / "metrics.json").read_text())
    assert summary["specs"] == {"player 0": "hkb:omega=2", "player 1": "adaptive:cp=50"}
    session = load_session(out / "session.parquet")
    described = session.metadata["players"]
    assert described[1]["class"] == "AdaptivePlayer" and described[1]["params"]["cp"] == 50.0
    assert summary["metrics"]["rmse"] < 0.2


def test_group_simulate_plays_every_partner(tmp_path: Path) -> None:
    out = tmp_path / "group"
    players = ["kuramoto", "kuramoto:omega=2.5,phase=1", "adaptive", "rpc", "hkb", "excitator"]
    arguments = ["group", "simulate", "--duration", "8", "--leader", "0", "--out", str(out)]
    for spec in players:
        arguments += ["--player", spec]
    assert main(arguments) == 0
    session = load_session(out / "session.parquet")
    assert session.n_players == 6
    assert [p["class"] for p in session.metadata["players"]] == [
        "KuramotoPlayer", "KuramotoPlayer", "AdaptivePlayer", "ReactivePredictivePlayer",
        "HKBPartner", "ExcitatorPartner",
    ]  # fmt: skip
    metrics = json.loads((out / "metrics.json").read_text())["metrics"]
    assert 0.0 <= metrics["group_synchronisation"] <= 1.0


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["train", "--target", "bundled:slow", "--partners", "adaptive", "--sessions", "2"],
         "adaptive: is a partner model; training needs a virtual trainer"),
        (["group", "train", "--target", "rpc", "--player", "bundled:slow", "--sessions", "2"],
         "rpc: is a partner model; training needs a virtual trainer"),
        (["simulate", "--leader", "bundled:slow", "--follower", "adaptive:gain=3"],
         "adaptive:gain=3: unknown parameter 'gain'; adaptive takes alpha, beta"),
    ],
)  # fmt: skip
def test_partners_refused_where_they_cannot_play_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], arguments: list[str], message: str
) -> None:
    out = tmp_path / "out.npz" if "train" in arguments else tmp_path / "out"
    assert main([*arguments, "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip()
    assert message in error and "\n" not in error
    assert not out.exists()
