"""`mirror-avatar lab pilot` under an emulated internet plays each partner view: the stand-ins'
pages draw and report their frames as a browser's does, so each trial has its view file, each
person's row of the study table its view delay and error, and the handlings differ as they
should: equalised, both persons see each other equally late; predicted, a smooth leader is drawn
nearer where it is than as its frames arrive."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mirror_avatar.lab.running.views import VIEW_COLUMNS

ROOT = Path(__file__).parents[2]
COMMAND = [sys.executable, "-c", "from mirror_avatar.console import run; run()"]

EQUAL_WITHIN_MS = 10.0
"""How close the two persons' mean view delays are when equalised (ms): each draw waits for an
animation frame (0 to 16.7 ms) alike on both pages; what remains is their clocks' offsets
(METHODS section 19)."""


def sway(path: Path) -> str:
    """Write a recorded trial of a smooth leader: 0.3 units at 0.4 Hz for 60 s; return its spec."""
    t = np.arange(0.0, 60.0, 0.01)
    frame = pd.DataFrame({"time": t, "position": 0.3 * np.sin(2 * np.pi * 0.4 * t)})
    frame.to_csv(path, index=False)
    return str(path)


@pytest.fixture(scope="module")
def piloted(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, pd.DataFrame]:
    """The example protocol, one trial of 5 s per handling, piloted at 120 +- 40 ms one way."""
    folder = tmp_path_factory.mktemp("views")
    text = (ROOT / "examples" / "protocols" / "delay_handling.toml").read_text(encoding="utf-8")
    for key, value in (("trials", "1"), ("duration", "5"), ("pause", "0")):
        text = re.sub(rf"^{key} = .*$", f"{key} = {value}", text, flags=re.MULTILINE)
    protocol = folder / "delay_handling.toml"
    protocol.write_text(text, encoding="utf-8")
    out = folder / "out"
    run = [*COMMAND, "lab", "pilot", "--protocol", str(protocol), "--participants", "1"]
    stand_ins = ["--stand-in", f"P1={sway(folder / 'sway.csv')}", "--stand-in", "P2=bundled:slow"]
    result = subprocess.run(
        [*run, *stand_ins, "--network", "120+-40", "--seed", "2", "--out", str(out)],
        capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    table = folder / "table"
    made = subprocess.run(
        [*COMMAND, "study", "table", str(out), "--out", str(table), "--surrogates", "0"],
        capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip
    assert made.returncode == 0, made.stderr
    return out / "delay_handling-p000", pd.read_csv(table / "study.csv")


@pytest.mark.long
def test_every_trial_of_a_pilot_has_its_view_file_and_each_person_its_view(piloted):
    run, table = piloted
    for n in (1, 2, 3):
        view = pd.read_csv(run / f"trial-0{n}_view.csv")
        assert tuple(view.columns) == VIEW_COLUMNS
        assert set(view.label) == {"P1", "P2"}, n
        assert np.all(np.diff(view[view.label == "P2"].shown_s) > 0), n
    assert set(table.partner_view) == {"as_arrives", "equalised", "predicted"}
    columns = ["page_view_delay_ms", "page_view_delay_p95_ms", "page_view_error_rms"]
    assert table[columns].notna().all().all(), table[["person", "partner_view", *columns]]


def handling(sidecar: Path) -> str:
    return str(json.loads(sidecar.read_text())["metadata"]["lab"]["partner_view"]["handling"])


def rows(table: pd.DataFrame, handling: str) -> pd.DataFrame:
    return table[table.partner_view == handling].set_index("person")


@pytest.mark.long
def test_equalised_both_persons_see_each_other_equally_late(piloted):
    _, table = piloted
    equalised = rows(table, "equalised").page_view_delay_ms
    assert abs(equalised["P1"] - equalised["P2"]) < EQUAL_WITHIN_MS, equalised
    arrives = rows(table, "as_arrives")
    spread = arrives.page_view_delay_p95_ms - arrives.page_view_delay_ms
    held = rows(table, "equalised")
    assert np.all(held.page_view_delay_p95_ms - held.page_view_delay_ms < spread), (held, arrives)


@pytest.mark.long
def test_predicted_the_smooth_leader_is_drawn_nearer_where_it_is_than_as_it_arrives(piloted):
    run, table = piloted
    follower_sees = {
        h: rows(table, h).page_view_error_rms["P2"] for h in ("as_arrives", "predicted")
    }
    assert follower_sees["predicted"] < follower_sees["as_arrives"], follower_sees
    # within the predicted trial, draw by draw: nearer than the samples it was predicted from
    (trial,) = [n for n in (1, 2, 3) if handling(run / f"trial-0{n}_session.json") == "predicted"]
    view = pd.read_csv(run / f"trial-0{trial}_view.csv")
    seen = view[view.label == "P2"]
    clock = pd.read_csv(run / f"trial-0{trial}_inputs.csv").clock_s.to_numpy()
    leader = pd.read_csv(run / f"trial-0{trial}_session.csv").position_0.to_numpy()
    truth = np.interp(seen.shown_s, clock, leader)
    predicted = np.sqrt(np.mean((seen.x - truth) ** 2))
    unpredicted = np.sqrt(np.mean((np.interp(seen.sample_s, clock, leader) - truth) ** 2))
    assert predicted < unpredicted, (predicted, unpredicted)
