"""`mirror-avatar lab pilot --network`: the virtual participants' pages behind an emulated
internet, its truth log in the pilot's folder, the round trips their clock exchanges recorded
those it drew; each person behind one of their own (`--network LABEL=SPEC`), the equalised
handling drawing both persons' partners equally late although their links differ."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_lab_pilot import ROOT, rehearsal, run_command

from mirror_avatar.cli import main
from mirror_avatar.lab.running.pilot import run_pilot

PROTOCOL = """
title = "Network pilot"
seed = 5

[[blocks]]
name = "main"
order = "fixed"

[[blocks.conditions]]
name = "solo"
game = "solo"
players = [{ label = "P1", kind = "person" }]
trials = 1
duration = 4
pause = 0
"""


@pytest.mark.long
def test_a_pilot_under_an_emulated_internet_writes_its_truth_beside_the_runs(tmp_path):
    protocol = tmp_path / "net.toml"
    protocol.write_text(PROTOCOL, encoding="utf-8")
    out = tmp_path / "out"
    result = subprocess.run(
        [
            sys.executable, "-c", "from mirror_avatar.console import run; run()", "lab", "pilot",
            "--protocol", str(protocol), "--participants", "1", "--seed", "3",
            "--network", "60+-10", "--out", str(out),
        ],
        capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "network 60+-10, its truth in pilot-network.csv" in result.stdout
    assert "participant 0: finished, 1 of 1 trial(s) complete" in result.stdout, result.stdout
    facts = json.loads((out / "pilot-network.json").read_text())
    assert facts["network"] == "60+-10" and facts["seed"] == 3
    truth = pd.read_csv(out / "pilot-network.csv", keep_default_na=False)
    (page,) = truth[truth.request.str.startswith("GET /ws/join/sha256:")].connection
    carried = truth[(truth.connection == page) & (truth.bytes > 0)]
    # the stand-in's positions (33 a second for 4 s) went up, the frames down, each delayed
    for direction in ("up", "down"):
        drawn = carried[carried.direction == direction].delay_ms.to_numpy()
        assert len(drawn) > 100, direction
        assert abs(drawn.mean() - 60.0) < 4 * 10.0 / np.sqrt(len(drawn)), direction
        took = carried[carried.direction == direction].eval("delivered_s - received_s")
        assert np.all(took >= drawn / 1000 - 1e-6), direction
    # the stand-in's page keeps its clock as a browser's does: its round trips are the proxy's
    # (each chunk held as long as it was: its drawn delay, or longer behind the one before it)
    sidecar = json.loads((out / "net-p000" / "trial-01_session.json").read_text())["metadata"]
    rtt = sidecar["pages"]["P1"]["rtt_ms"]
    held = carried.eval("delivered_s - received_s").groupby(carried.direction).median()
    proxied = 1000.0 * held.sum()
    assert rtt["n"] > 20 and proxied - 10.0 <= rtt["median"] <= proxied + 20.0, (rtt, proxied)


@pytest.mark.long
def test_a_stand_in_screened_out_under_the_network_ends_the_pilot_in_one_line(tmp_path):
    protocol = tmp_path / "screened.toml"
    screening = "[online]\nscreen_round_trip_p95_ms = 150\n\n[[blocks]]"
    protocol.write_text(PROTOCOL.replace("[[blocks]]", screening, 1), encoding="utf-8")
    result = subprocess.run(
        [
            sys.executable, "-c", "from mirror_avatar.console import run; run()", "lab", "pilot",
            "--protocol", str(protocol), "--participants", "1", "--seed", "3",
            "--network", "150+-10", "--out", str(tmp_path / "out"),
        ],
        capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip
    assert result.returncode == 2, result.stderr
    error = result.stderr.strip()
    assert error.count("\n") == 0 and "--stand-in P1: screened out" in error, error
    assert "is above the study's 150 ms" in error and "--network" in error


def test_a_pilot_refuses_a_bad_network_before_anything_starts(tmp_path, capsys):
    out = tmp_path / "out"
    protocol = tmp_path / "net.toml"
    protocol.write_text(PROTOCOL, encoding="utf-8")
    arguments = ["--protocol", str(protocol), "--network", "60+-10,stall=3", "--out", str(out)]
    assert main(["lab", "pilot", *arguments]) == 2
    error = capsys.readouterr().err.strip()
    assert "--network: stall='3' is not START:SECONDS" in error and "\n" not in error
    assert not out.exists()


@pytest.mark.long
def test_a_stand_in_draws_and_sizes_its_page_as_a_browser_and_is_admitted(tmp_path):
    protocol = tmp_path / "framed.toml"
    screening = "[online]\nscreen_frame_rate_hz = 30\nscreen_window_width_px = 800\n\n[[blocks]]"
    protocol.write_text(PROTOCOL.replace("[[blocks]]", screening, 1), encoding="utf-8")
    (status,) = run_pilot(protocol, tmp_path / "out", range(1), {"P1": "bundled:slow"}, seed=3)
    assert status["state"] == "finished"
    (admitted,) = [event for event in status["events"] if "P1 admitted" in event]
    assert admitted.endswith("frames/s, window 1280x720 px"), admitted
    # a stand-in draws on 60 Hz animation frames of its own clock, fewer on a busy machine
    assert float(admitted.split(" ms, ")[1].split(" frames/s")[0]) >= 30, admitted


ONE_WAY_MS = {"P1": 20.0, "P2": 150.0}
"""Each person's link in the per-person pilot (mean one-way delay, ms; SD 5 and 10 ms, so that
nearly every chunk is held its own delay, seldom behind the one before)."""

EQUAL_WITHIN_MS = 20.0
"""How close the two persons' mean view delays are when equalised over unequal links (ms). Each
draw waits for an animation frame (0 to 16.7 ms) alike on both pages; the near page draws every
frame at its due time, but the far page draws those that reach it after the lag (half its
round trips' 95th percentile, the machine's own latency in them) as they arrive, late, more of
them the busier the pilot's process; and the two clocks' offsets differ (METHODS section 19)."""

RTT_WITHIN_MS = 30.0
"""How close the difference of the two persons' median round trips is to the declared one
(ms): both round trips hold the same server and machine; each median is of round trips
drawn with an SD of 7 and 14 ms."""


@pytest.fixture(scope="module")
def per_person(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str, pd.DataFrame]:
    """The delay-handling template, one 5 s trial per handling, P1 at 20 and P2 at 150 ms."""
    folder = tmp_path_factory.mktemp("people")
    protocol = rehearsal(ROOT / "examples" / "protocols" / "delay_handling.toml", folder, 5.0)
    out = folder / "out"
    result = run_command(
        "lab", "pilot", "--protocol", str(protocol), "--participants", "1", "--seed", "4",
        "--network", "P1=20+-5", "--network", "P2=150+-10", "--out", str(out),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    table = folder / "table"
    made = run_command("study", "table", str(out), "--out", str(table), "--surrogates", "0")
    assert made.returncode == 0, made.stderr
    return out, result.stdout, pd.read_csv(table / "study.csv")


@pytest.mark.long
def test_each_person_joins_through_their_own_network_its_truth_logged(per_person):
    out, stdout, _ = per_person
    assert (
        "networks P1 20+-5 (truth in pilot-network-P1.csv), "
        "P2 150+-10 (truth in pilot-network-P2.csv)"
    ) in stdout, stdout
    assert not (out / "pilot-network.csv").exists()
    seeds = set()
    for label, one_way in ONE_WAY_MS.items():
        facts = json.loads((out / f"pilot-network-{label}.json").read_text())
        assert facts["network"].split("+-")[0] == f"{one_way:g}"
        seeds.add(facts["seed"])
        truth = pd.read_csv(out / f"pilot-network-{label}.csv", keep_default_na=False)
        # one page (the person's), through its own proxy: its WebSocket, its intro and consent
        # are the researcher's API's, not a page's
        (page,) = truth[truth.request.str.startswith("GET /ws/join/sha256:")].connection
        drawn = truth[(truth.connection == page) & (truth.bytes > 0)].delay_ms
        assert abs(drawn.mean() - one_way) < 1.0, (label, drawn.mean())
    assert len(seeds) == 2, "the two networks drew the same delays"


@pytest.mark.long
def test_equalised_both_persons_see_each_other_equally_late_over_unequal_links(per_person):
    _, _, table = per_person
    by = table.set_index(["partner_view", "person"])
    equalised = by.loc["equalised"].page_view_delay_ms
    assert abs(equalised["P1"] - equalised["P2"]) < EQUAL_WITHIN_MS, equalised
    arrives = by.loc["as_arrives"].page_view_delay_ms
    assert arrives["P2"] - arrives["P1"] > 100.0, arrives  # 150 - 20 ms apart, unequalised
    # the links' round trips differ as declared: 2 x (150 - 20) ms, in every trial
    rtt = table.pivot(index="partner_view", columns="person", values="page_rtt_median_ms")
    declared = 2.0 * (ONE_WAY_MS["P2"] - ONE_WAY_MS["P1"])
    assert np.all(abs(rtt.P2 - rtt.P1 - declared) < RTT_WITHIN_MS), rtt


def test_a_pilot_refuses_a_network_for_nobody_in_one_line(tmp_path, capsys):
    out = tmp_path / "out"
    protocol = tmp_path / "net.toml"
    protocol.write_text(PROTOCOL, encoding="utf-8")
    for network, problem in (
        (["P9=20"], "--network: 'P9=20': P9 is no person of the protocol (its people: P1)"),
        (["P1=20", "P1=30"], "--network: 'P1=30': a second network for person P1"),
        (["20", "none"], "--network: 'none': a second network for every person"),
        (["P1=20+-"], "--network: '20+-' is not a delay"),
    ):
        arguments = ["--protocol", str(protocol), *[f"--network={v}" for v in network]]
        assert main(["lab", "pilot", *arguments, "--out", str(out)]) == 2
        error = capsys.readouterr().err.strip()
        assert problem in error and "\n" not in error, error
    assert not out.exists()
