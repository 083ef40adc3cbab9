"""``mirror-avatar benchmark`` and the adaptive player against real recorded leaders."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mirror_avatar.cli import main
from mirror_avatar.experiments.partner_benchmark import (
    PUBLISHED_ADAPTIVE_BOUNDS,
    SCORES,
    BenchmarkResult,
    relative_position_error,
    run_benchmark,
)
from mirror_avatar.specs import bundled_generator
from mirror_avatar.trial_files import write_trial
from mirror_avatar.trials import Trial


@pytest.fixture(autouse=True)
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Fitted bundled generators go to a per-test cache."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    bundled_generator.cache_clear()


def test_adaptive_player_keeps_the_published_bounds_on_slow_real_leaders(
    zhai_trials_100hz: list[Trial],
) -> None:
    """Zhai et al.: the adaptive player's errors stay small where the RPC's reach 0.8 and 3.

    On the nine bundled slow leaders its RMS position error stays under the published position
    bound and its RMS velocity error under the published velocity bound on every trial, and its
    largest position error is below the reactive-predictive controller's on every trial. (Its
    largest errors are in the benchmark report: the recordings' tracking drop-outs are velocity
    spikes of the leader no follower matches.)
    """
    slow = [trial for trial in zhai_trials_100hz if trial.group == "slow"]
    result = run_benchmark(slow, ["adaptive", "rpc"], progress=False)
    table = result.trials.pivot(index="trial", columns="follower")
    assert len(table) == 9
    assert (table["rms", "adaptive"] < PUBLISHED_ADAPTIVE_BOUNDS["position"]).all()
    assert (table["rms_velocity_error", "adaptive"] < PUBLISHED_ADAPTIVE_BOUNDS["velocity"]).all()
    assert (table["max_position_error", "adaptive"] < table["max_position_error", "rpc"]).all()
    assert (table["max_position_error", "rpc"] > 0.5).all()


def test_relative_position_error_follows_zhai_et_al_by_hand() -> None:
    """Zhai et al. (2017), section 6.2: the signed gap where both move the same way, else |gap|."""
    leader = np.array([0.3, 0.3, 0.3, 0.3, 0.3])
    follower = np.array([0.1, 0.5, 0.1, 0.1, 0.5])
    leader_velocity = np.array([1.0, 1.0, -1.0, 1.0, 0.0])
    follower_velocity = np.array([2.0, 0.5, -0.5, -1.0, 0.0])
    # moving right together, behind: +0.2; moving right together, ahead: -0.2; moving left
    # together, follower on the left (ahead): -0.2; opposite ways: |0.2|; both still: |-0.2|
    expected = (0.2 - 0.2 - 0.2 + 0.2 + 0.2) / 5
    value = relative_position_error(leader, follower, leader_velocity, follower_velocity)
    assert value == pytest.approx(expected)
    t = np.linspace(0.0, 20.0, 2001)
    # a follower 0.1 rad behind a sine: e(t) = 2 sin(0.05) |cos(t - 0.05)| up to the samples
    # where the two move opposite ways, mean about 0.1 * 2 / pi
    rpe = relative_position_error(np.sin(t), np.sin(t - 0.1), np.cos(t), np.cos(t - 0.1))
    assert rpe == pytest.approx(0.2 / np.pi, rel=0.02)


def test_benchmark_command_writes_table_results_report_and_figures(
    tmp_path: Path, zhai_trials: list[Trial], capsys: pytest.CaptureFixture[str]
) -> None:
    files = []
    for k, trial in enumerate(zhai_trials[:2] + zhai_trials[9:11]):
        files.append(tmp_path / f"trial{k}.csv")
        write_trial(trial, files[-1])
    out = tmp_path / "bench"
    arguments = ["benchmark", "--models", "adaptive,rpc,hkb,excitator,kuramoto,vt", "--out"]
    arguments += [str(out), "--leader", str(files[0]), "--leader", str(files[2])]
    arguments += ["--human", str(files[1]), "--human", str(files[3])]
    assert main(arguments) == 0
    printed = capsys.readouterr().out
    assert "ranking" in printed
    table = pd.read_csv(out / "table.csv", index_col="follower")
    assert list(table.index) == ["adaptive", "rpc", "hkb", "excitator", "kuramoto", "vt", "human"]
    assert (table["trials"] == 2).all()
    assert table.loc["rpc", "published_rpe"] == 0.3838
    assert table.loc["excitator", "published_time_lag"] == -0.9674
    results = json.loads((out / "results.json").read_text())
    assert sorted(results["ranking_by_rpe_nearest_human"]) == sorted(table.index[:-1])
    assert results["published"]["rpe"]["human"] == 0.0914
    trials = pd.read_csv(out / "trials.csv")
    human = trials[trials.follower == "human"].iloc[0]
    assert human.rms == pytest.approx(
        float(np.sqrt(np.mean((zhai_trials[0].positions - zhai_trials[1].positions) ** 2))),
        rel=0.2,
    )
    for name in table.index:
        assert (out / f"{name}.png").read_bytes().startswith(b"\x89PNG")
    report = (out / "report.html").read_text()
    assert "0.0816" in report and "2.1767" in report and "<img" in report
    assert "Ranking by RPE nearest the recorded human followers" in report


def test_benchmark_refuses_bad_models_and_unpaired_humans(
    tmp_path: Path, zhai_trials: list[Trial], capsys: pytest.CaptureFixture[str]
) -> None:
    leader = tmp_path / "leader.csv"
    write_trial(zhai_trials[0], leader)
    out = tmp_path / "bench"
    base = ["benchmark", "--leader", str(leader), "--out", str(out)]
    assert main([*base, "--models", "adaptive,opc"]) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and "unknown model opc" in error and "kuramoto" in error
    other = tmp_path / "other.csv"
    write_trial(zhai_trials[1], other)
    assert main([*base, "--models", "rpc", "--human", str(leader), "--human", str(other)]) == 2
    assert "one human follower per leader" in capsys.readouterr().err
    assert main([*base, "--models", "hkb:zeta=1"]) == 2
    assert "unknown parameter 'zeta'; hkb takes alpha" in capsys.readouterr().err
    assert not out.exists()


def test_without_recorded_humans_the_human_row_is_zhai_et_als() -> None:
    """The human row then has no trial of ours; the ranking measures from the published 0.0914."""
    rows = [
        {"follower": name, "trial": "t", "group": "slow"}
        | dict.fromkeys(SCORES, 0.0)
        | {"rpe": rpe}
        for name, rpe in [("vt", 0.05), ("rpc", 0.095), ("hkb", 0.3)]
    ]
    result = BenchmarkResult(pd.DataFrame(rows), {})
    table = result.summary()
    assert table.loc["human", "trials"] == 0 and np.isnan(table.loc["human", "rpe"])
    assert table.loc["human", "published_rpe"] == 0.0914
    assert result.human_rpe() == 0.0914
    assert result.ranking() == ["rpc", "vt", "hkb"]
