"""A template of the field's designs run in real browsers through to its report: the console
creates a participant's run of Llobera et al. 2022's three-arm blinded design (a person, a
coupled and an uncoupled avatar), two people's pages play and answer "person or computer?", and
`study table` and `study report` turn the run folder into the study's results."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from browsers import SCREENSHOTS
from test_lab_pilot import rehearsal
from test_lab_study_browser import join
from test_lab_study_protocol_browser import answer, create_run, move_until

from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread

pytestmark = pytest.mark.browser

TOKEN = "template-token"
TEMPLATE = Path(__file__).parents[2] / "examples" / "protocols" / "llobera2022.toml"
REPORT = "study-report.png"


def run_command(*arguments: str) -> None:
    command = "from mirror_avatar.console import run; run()"
    result = subprocess.run(
        [sys.executable, "-c", command, *arguments],
        capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr


@pytest.mark.long
def test_a_templated_study_runs_from_the_console_to_its_report(chromium, tmp_path):
    protocol = load_protocol(rehearsal(TEMPLATE, tmp_path))
    out = tmp_path / "out"
    settings = LabSettings(out_dir=out, token=TOKEN, countdown=1, protocol=protocol)
    with ServerThread(create_lab_app(settings)) as lab:
        console, links, sid, study = create_run(chromium, lab.url, TOKEN, out, 0)
        pages = {
            label: join(chromium.new_context(viewport={"width": 900, "height": 600}), links[label])
            for label in ("P1", "P2")
        }
        for label in pages:
            console.wait_for_selector(f'tr[data-label="{label}"] td.state.connected')
        console.click("#start")
        for condition in study["order"]:
            for n in condition["trials"]:
                playing = [
                    page
                    for label, page in pages.items()
                    if condition["players"].get(label) == "human"
                ]
                move_until(playing, "!document.getElementById('questions').hidden")
                for page in playing:
                    answer(page, n, touch=False)
        console.wait_for_function("document.getElementById('state').textContent === 'finished'")
        for page in [console, *pages.values()]:
            page.context.close()

    run_command("study", "table", str(out), "--out", str(tmp_path / "results"))
    run_command("study", "report", str(tmp_path / "results"), "--out", str(tmp_path / "report"))
    table = pd.read_csv(tmp_path / "results" / "study.csv")
    people = table[table["player_kind"] == "person"]
    assert set(people["condition"]) == {"human", "coupled", "uncoupled"}
    kinds = people.groupby("condition")["partner_kind"].first().to_dict()
    assert kinds == {"human": "person", "coupled": "avatar", "uncoupled": "avatar"}
    assert people["guess_kind"].notna().all() and people["guess_confidence"].notna().all()
    results = json.loads((tmp_path / "report" / "results.json").read_text())
    assert results["identification"]["answers"] == len(people)
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    report = chromium.new_context(viewport={"width": 1280, "height": 900}).new_page()
    report.goto((tmp_path / "report" / "report.html").as_uri())
    assert report.evaluate("document.documentElement.scrollWidth") <= 1280
    report.screenshot(path=SCREENSHOTS / REPORT, full_page=True)
    report.context.close()
