"""``mirror-avatar group simulate`` / ``group train`` and ``evaluate`` of groups."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.deep.player import load_deep_cyber_player
from mirror_avatar.files.trials import Trial
from mirror_avatar.learning.agent import load_cyber_player
from mirror_avatar.metrics import session_metrics
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.sessions.graphs import path_graph
from mirror_avatar.sessions.loading import load_session


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory, zhai_trials_100hz: list[Trial]) -> list[str]:
    folder = tmp_path_factory.mktemp("models")
    paths = []
    for name, trials in (("fast", zhai_trials_100hz[0:3]), ("slow", zhai_trials_100hz[9:12])):
        path = folder / f"{name}.npz"
        IMSGenerator(n_symbols=32, random_state=0).fit(trials).save(path)
        paths.append(str(path))
    return paths


def simulate(out: Path, *players: str, extra: tuple[str, ...] = ()) -> int:
    arguments = ["group", "simulate", "--duration", "10", "--seed", "4", "--out", str(out)]
    return main(arguments + [a for p in players for a in ("--player", p)] + list(extra))


@pytest.mark.long
def test_group_simulate_writes_the_session_and_group_metrics(tmp_path, models, capsys) -> None:
    fast, slow = models
    out = tmp_path / "sim"
    assert simulate(out, fast, slow, slow, fast, extra=("--graph", "path")) == 0
    printed = capsys.readouterr().out
    assert "group synchronisation" in printed and "Kuramoto" in printed
    session = load_session(out / "session.parquet")
    assert session.n_players == 4 and session.roles == ("group",) * 4
    np.testing.assert_array_equal(session.graph, path_graph(4))
    np.testing.assert_array_equal(load_session(out / "session.csv").positions, session.positions)
    summary = json.loads((out / "metrics.json").read_text())
    assert summary["graph"] == path_graph(4).tolist() and summary["seed"] == 4
    expected = session_metrics(session, trim=1.0)
    assert summary["metrics"]["group_synchronisation"] == pytest.approx(
        expected["group_synchronisation"]
    )
    assert [p["neighbours"] for p in summary["metrics"]["players"]] == [[1], [0, 2], [1, 3], [2]]
    assert main(["evaluate", str(out / "session.csv")]) == 0
    assert "group synchronisation" in capsys.readouterr().out


def test_leaders_and_a_graph_file(tmp_path, models) -> None:
    fast, slow = models
    graph = tmp_path / "chain.json"
    graph.write_text(json.dumps({"adjacency": path_graph(3).tolist()}))
    out = tmp_path / "led"
    assert simulate(out, slow, fast, slow, extra=("--graph", str(graph), "--leader", "1")) == 0
    session = load_session(out / "session.parquet")
    assert session.roles == ("group", "group_leader", "group")
    assert session.metadata["players"][1]["params"]["theta_p"] == 0.2


@pytest.mark.parametrize(
    ("players", "extra", "problem"),
    [
        (1, (), "at least two players"),
        (3, ("--leader", "3"), "--leader"),
        (3, ("--graph", "lattice"), "not a topology"),
        (3, ("--graph", "missing.csv"), "no such file"),
    ],
)
def test_bad_groups_are_one_line(tmp_path, models, capsys, players, extra, problem) -> None:
    assert simulate(tmp_path / "x", *[models[1]] * players, extra=extra) == 2
    error = capsys.readouterr().err
    assert problem in error and error.count("\n") == 1


@pytest.mark.long
def test_group_train_writes_a_policy_that_plays_anywhere(tmp_path, models, capsys) -> None:
    fast, slow = models
    policy = tmp_path / "member.npz"
    arguments = ["group", "train", "--target", slow, "--player", fast, "--player", slow]
    arguments += ["--sessions", "6", "--duration", "4", "--jobs", "1", "--agent", "tabular"]
    assert main([*arguments, "--out", str(policy)]) == 0
    player = load_cyber_player(policy)
    assert player.training_["role"] == "group" and player.training_["n_sessions"] == 6
    assert (tmp_path / "member.learning_curve.csv").is_file()
    assert (tmp_path / "member.learning_curve.png").is_file()
    capsys.readouterr()
    assert simulate(tmp_path / "with", fast, slow, str(policy), extra=("--graph", "random")) == 0
    assert "player 2: EMD to its target's IMS" in capsys.readouterr().out
    session = load_session(tmp_path / "with" / "session.parquet")
    assert np.all(np.isfinite(session.controls[2, :-1]))  # the cyber player reports controls
    assert main(["evaluate", str(tmp_path / "with"), "--out", str(tmp_path / "table")]) == 0
    assert "emd_target_2" in (tmp_path / "table" / "sessions.csv").read_text().splitlines()[0]
    dyad = ["simulate", "--leader", fast, "--follower", str(policy), "--duration", "5",
            "--out", str(tmp_path / "dyad")]  # fmt: skip
    assert main(dyad) == 2  # trained in a group, not as a follower
    assert main([*dyad, "--joint"]) == 0


def test_group_train_trains_the_deep_player_by_default(tmp_path, models, capsys) -> None:
    """The group cyber player is the DQN unless --agent tabular is given, whose help says that
    it does not meet the group criteria; --sessions defaults to the agent's own length."""
    fast, slow = models
    assert main(["group", "train", "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())
    assert "[default: 4000 for tabular, 300 for dqn]" in help_text
    assert "does not meet the group criteria. [default: dqn]" in help_text
    policy = tmp_path / "member.npz"
    arguments = ["group", "train", "--target", slow, "--player", fast, "--player", slow,
                 "--sessions", "3", "--duration", "4", "--jobs", "1",
                 "--out", str(policy)]  # fmt: skip
    assert main(arguments) == 0
    assert "trained a dqn group member on 3 sessions" in capsys.readouterr().out
    player = load_deep_cyber_player(policy)
    assert player.training_["agent"] == "dqn" and player.training_["n_sessions"] == 3
