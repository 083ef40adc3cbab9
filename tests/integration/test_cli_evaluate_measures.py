"""The field's measures through ``mirror-avatar evaluate``: table, JSON, CSV, report and options.

Sessions of every origin the toolkit reads: a simulated dyad, an imported pair with a known
leader, a live trial against an avatar, a lab trial and its BIDS export, and groups.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.lab.design.plan import parse_plan
from mirror_avatar.lab.running.trial import LabTrial, build_avatars
from mirror_avatar.live.messages import StartRequest
from mirror_avatar.live.session import make_avatar_factory, start_trial
from mirror_avatar.realtime.inputs import BrowserInput
from mirror_avatar.testing import smooth_motion

MEASURES = (
    "co_confidence_rate", "co_confidence_segments", "jitter_index_player_0", "leader",
    "leader_lag_s", "transfer_entropy_0_to_1", "transfer_entropy_1_to_0",
    "phase_locking_p_value", "rmse_p_value", "time_lag_p_value", "co_confidence_rate_p_value",
    "leader_share_p_value", "transfer_entropy_0_to_1_p_value", "synchrony_entries",
)  # fmt: skip


def write_pair(path: Path, rng: np.random.Generator, delay: int, rate: float = 50.0) -> None:
    """An imported pair: player 1 repeats player 0 ``delay`` samples later."""
    s = 0.3 * smooth_motion(rng, 1500 + delay, rate) / 0.1
    lines = ["time,position_0,position_1"] + [
        f"{k / rate:.4f},{s[k + delay]:.6f},{s[k]:.6f}" for k in range(1500)
    ]
    path.write_text("\n".join(lines) + "\n")


def write_group(path: Path, rng: np.random.Generator, coupled: bool, rate: float = 50.0) -> None:
    """Three players: each a delayed copy of one motion (coupled) or their own motions."""
    s = [smooth_motion(rng, 1010, rate) for _ in range(3)]
    rows = [s[0][10 - 5 * i : 1010 - 5 * i] if coupled else s[i][:1000] for i in range(3)]
    lines = ["time,position_0,position_1,position_2"] + [
        f"{k / rate:.4f}," + ",".join(f"{r[k]:.6f}" for r in rows) for k in range(1000)
    ]
    path.write_text("\n".join(lines) + "\n")


def evaluate(capsys: pytest.CaptureFixture[str], *arguments: str) -> tuple[int, str, str]:
    capsys.readouterr()
    status = main(["evaluate", *arguments])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.mark.long
def test_an_imported_pair_with_a_known_leader(tmp_path, rng, capsys):
    pair = tmp_path / "pair.csv"
    write_pair(pair, rng, delay=10)
    out = tmp_path / "out"
    status, printed, _ = evaluate(capsys, str(pair), "--surrogates", "19", "--out", str(out))
    assert status == 0
    assert "CC rate" in printed and "leader (windowed cross-correlation)" in printed
    assert "transfer entropy 0 -> 1" in printed and "19 shift surrogates" in printed
    metrics = json.loads((out / "metrics.json").read_text())
    found = metrics["sessions"][str(pair)]
    assert set(MEASURES) <= set(found)
    assert found["leader"] == 0 and found["leader_lag_s"] == pytest.approx(0.2, abs=0.02)
    assert found["transfer_entropy_0_to_1"] > found["transfer_entropy_1_to_0"]
    assert found["phase_locking_p_value"] == pytest.approx(0.05)  # 1/20: beats all 19
    assert found["co_confidence_segments"] == []  # 0.2 s apart is not co-confident
    assert metrics["measures"]["options"]["n_surrogates"] == 19
    assert metrics["measures"]["options"]["seed"] == 0 and found["surrogates"]["n"] == 19
    header = (out / "sessions.csv").read_text().splitlines()[0].split(",")
    assert {"co_confidence_rate", "leader", "leader_lag_s", "rmse_p_value"} <= set(header)
    report = (out / "report.html").read_text()
    for figure in ("timeline", "leadership", "surrogates"):
        assert f"{tmp_path.name}/pair.csv: {figure}" in report


def test_the_seed_fixes_the_p_values_and_options_reach_the_measures(tmp_path, rng, capsys):
    pair = tmp_path / "pair.csv"
    write_pair(pair, rng, delay=1)
    runs = []
    for seed in ("3", "3", "4"):
        status, printed, _ = evaluate(
            capsys, str(pair), "--json", "--surrogates", "9", "--surrogate-seed", seed,
            "--lead-max-lag", "0.5", "--cc-min-duration", "3",
        )  # fmt: skip
        assert status == 0
        runs.append(json.loads(printed))
    assert runs[0] == runs[1]
    assert runs[0]["surrogates"]["seed"] != runs[2]["surrogates"]["seed"]
    segments = runs[0]["co_confidence_segments"]
    assert segments and all(s["end"] - s["start"] >= 3.0 - 1e-9 for s in segments)
    assert segments[0].keys() == {"start", "end", "dv", "dt"}


@pytest.mark.long
def test_pseudo_pairs_need_other_sessions(tmp_path, rng, capsys):
    for name in ("a.csv", "b.csv", "c.csv"):
        write_pair(tmp_path / name, rng, delay=5)
    status, printed, _ = evaluate(
        capsys, str(tmp_path), "--surrogate-kind", "pseudo", "--out", str(tmp_path / "o")
    )
    assert status == 0 and "weak-null test" in printed
    found = json.loads((tmp_path / "o" / "metrics.json").read_text())["sessions"]
    assert {m["surrogates"]["n"] for k, m in found.items() if k != "trim"} == {2}
    status, _, error = evaluate(capsys, str(tmp_path / "a.csv"), "--surrogate-kind", "pseudo")
    assert status == 2 and error.count("\n") == 1 and "--surrogates pseudo" in error


def test_groups_get_influence_and_the_weak_null_test(tmp_path, rng, capsys):
    for k in range(3):
        write_group(tmp_path / f"coupled-{k}.csv", rng, coupled=True)
    status, printed, _ = evaluate(capsys, str(tmp_path), "--surrogates", "19", "--json")
    assert status == 0
    head, _, tail = printed.partition("weak-null")
    found = json.loads(head)
    assert "one-sided p" in tail
    for metrics in found.values():
        assert metrics["influence_player_0"] > metrics["influence_player_2"]
        assert metrics["group_synchronisation_p_value"] == pytest.approx(0.05)


def test_simulated_live_lab_and_bids_sessions_print_the_measures(tmp_path, zhai_trials, capsys):
    sim = tmp_path / "sim"
    arguments = ["simulate", "--leader", "bundled:fast", "--follower", "bundled:slow"]
    assert main([*arguments, "--duration", "20", "--seed", "2", "--out", str(sim)]) == 0
    trial = start_trial(
        tmp_path / "live", StartRequest("avatar_follows", "P01", 20.0, seed=1),
        make_avatar_factory("bundled:slow"), "bundled:slow",
    )  # fmt: skip
    for x in zhai_trials[9].resampled(1 / 0.03).positions[: trial.n_ticks]:
        trial.update_person(float(x), None)
        trial.tick()
    trial.finish(True, "completed")
    live = next((tmp_path / "live" / "P01").glob("*_session.csv"))
    lab = tmp_path / "lab" / "20261125T010203-001"
    lab.mkdir(parents=True)
    plan = parse_plan(
        {"condition": "leader_follower", "duration": 20.0, "trials": 1, "leaders": [0],
         "players": [{"label": "P1", "kind": "human"},
                     {"label": "A1", "kind": "avatar", "spec": "bundled:slow"}]}
    )  # fmt: skip
    inputs = {k: BrowserInput() for k in plan.humans}
    session = {"session_id": lab.name, "condition": plan.condition}
    lab_trial = LabTrial(plan, 1, lab, inputs, build_avatars(plan), time.monotonic, session)
    while not lab_trial.finished:
        for source in inputs.values():
            source.put(0.3 * math.sin(2 * math.pi * 0.5 * lab_trial.k * 0.03), lab_trial.k)
        lab_trial.tick()
    lab_trial.finish(True, "completed")
    bids = tmp_path / "bids"
    assert main(["lab", "export", str(lab), "--out", str(bids)]) == 0
    files = [
        sim / "session.parquet", live, next(lab.glob("*_session.csv")),
        next(bids.glob("sub-*/motion/*_motion.tsv")),
    ]  # fmt: skip
    for file in files:
        status, printed, _ = evaluate(capsys, str(file), "--surrogates", "9")
        assert status == 0, file
        assert "CC rate" in printed and "leader" in printed and "p = " in printed, file
