"""`mirror-avatar lab pilot --network`: the virtual participants' pages behind an emulated
internet, its truth log in the pilot's folder, the round trips their clock exchanges recorded
those it drew."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

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
