"""An avatar's card says, role by role, where the avatar is further from its person than they
vary, and reads whole at a laptop's 1280 px (issues 38.3 and 39.3)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from mirror_avatar.cli import main
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.trial_io import write_csv_trial
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.training.avatar import load_avatar

WIDTH = 1280


@pytest.fixture(scope="module")
def card(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The avatar of a person of the bundled slow style (three real trials), trained with a
    partner of the fast style and validated with one of the slow style too: as follower it moves
    with its fast partner, about 4 times further from the person than their own trials are from
    one another (the situation of issue 38)."""
    folder = tmp_path_factory.mktemp("card")
    (folder / "trials").mkdir()
    trials = load_zhai2017()
    for trial in trials[9:12]:
        write_csv_trial(trial, folder / "trials" / f"{trial.label}.csv")
    fast, slow = folder / "fast.npz", folder / "slow.npz"
    IMSGenerator(n_symbols=32, random_state=0).fit(trials[:3]).save(fast)
    IMSGenerator(n_symbols=32, random_state=0).fit(trials[12:15]).save(slow)
    out = folder / "S01.npz"
    status = main(["avatar", "create", str(folder / "trials"), "--name", "S01", "--partners",
                   f"{fast},{slow}", "--sessions", "200", "--jobs", "1",
                   "--out", str(out)])  # fmt: skip
    assert status == 0
    return out


@pytest.mark.long
def test_the_card_flags_a_follower_far_from_its_person(card: Path) -> None:
    held = load_avatar(card).summary["proof"]["held_out"]
    assert held["folds"] == [["slow-1"], ["slow-2"], ["slow-3"]]
    assert held["scheme"] == "leave-one-out over 3 trials"
    follower = held["roles"]["follower"]
    assert follower["flagged"] and 3 < follower["ratio_to_own"] < 7
    assert follower["emd_to_held_out"] > held["own_emd_range"][1]
    assert set(held["roles"]) == {"follower", "leader", "group member"}
    verdict = load_avatar(card).summary["verdict"]
    assert verdict.startswith("The avatar moves ") and "FLAGGED" in verdict
    assert f"FLAGGED as follower ({follower['ratio_to_own']:.1f} x the person's own EMD)" in verdict
    page = card.with_suffix(".html").read_text()
    lead = page.index('<p class="lead">')
    assert page.index(verdict.replace("'", "&#39;")) > lead  # the verdict leads the page
    sentences = [held["roles"][role]["verdict"] for role in ("follower", "leader", "group member")]
    assert sentences[0].startswith("As follower, FLAGGED")
    for sentence in sentences:
        assert sentence.replace("'", "&#39;") in page
    assert "FLAGGED: above the person's own 95th percentile" in page  # a table cell
    assert "EMD P5" not in page and "EMD P95" not in page


@pytest.mark.long
@pytest.mark.browser
def test_the_card_reads_whole_at_1280_px(chromium: Any, card: Path, tmp_path: Path) -> None:
    page = chromium.new_page(viewport={"width": WIDTH, "height": 900})
    page.goto(card.with_suffix(".html").as_uri())
    assert page.evaluate("document.documentElement.scrollWidth") <= WIDTH
    cut = page.evaluate(
        "[...document.querySelectorAll('figure, table, p, img')]"
        ".filter(e => e.scrollWidth > e.clientWidth + 1 || e.getBoundingClientRect().right > "
        f"{WIDTH}).map(e => e.tagName + ': ' + e.textContent.slice(0, 60))"
    )
    assert cut == []
    shot = tmp_path / "avatar-card-1280.png"
    page.screenshot(path=str(shot), full_page=True)
    assert shot.stat().st_size > 10_000
    page.close()
