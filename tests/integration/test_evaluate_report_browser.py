"""evaluate's report in Chromium at a laptop's width: its verdict first, columns in words, nothing
cut off."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest

from mirror_avatar.cli import main
from mirror_avatar.metrics import registry

pytestmark = pytest.mark.browser

WIDTH = 1280
SESSIONS = Path(__file__).parents[1] / "fixtures" / "evaluate_before" / "sessions"


@pytest.mark.long
def test_the_evaluate_report_leads_with_its_verdict_in_words_at_1280_px(
    chromium: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    shutil.copytree(SESSIONS, tmp_path / "sessions")
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", "sessions", "--surrogates", "39", "--out", "out"]) == 0
    page = chromium.new_page(viewport={"width": WIDTH, "height": 900})
    page.goto((tmp_path / "out" / "report.html").as_uri())
    assert page.evaluate("document.documentElement.scrollWidth") <= WIDTH
    # every table fits its box: none scrolls sideways, so no column is cut off
    widths = page.eval_on_selector_all(
        "figure.table", "fs => fs.map(f => [f.scrollWidth, f.clientWidth])"
    )
    assert widths and all(scroll <= client for scroll, client in widths), widths
    lead = page.locator("p.lead").inner_text()
    assert lead.startswith("2 of the 4 sessions tested are coordinated beyond chance")
    assert "lab/trial-01_session.csv, simulated.parquet" in lead
    assert "player 0 (P1)" in page.locator("table").last.inner_text()  # the lab trial's leader
    headers = page.eval_on_selector_all("th", "hs => hs.map(h => h.innerText)")
    assert registry.heading("rmse") in headers and registry.heading("time_lag") in headers
    rows = page.eval_on_selector_all("tbody th", "hs => hs.map(h => h.innerText)")
    assert registry.heading("transfer_entropy_0_to_1") in rows
    assert "figure" in headers  # where each measure is drawn
    raw = {key for key in json.loads((tmp_path / "out" / "metrics.json").read_text())["sessions"]
           ["sessions/bundled_pair.csv"]}  # fmt: skip
    assert not raw & set(headers + rows)  # no raw key names a column or a row
    header = (tmp_path / "out" / "sessions.csv").read_text().splitlines()[0].split(",")
    assert {"phase_locking", "rmse", "time_lag_p_value"} <= set(header)  # raw names stay there
    page.screenshot(path=str(tmp_path / "evaluate-report-1280.png"), full_page=True)
    page.close()
