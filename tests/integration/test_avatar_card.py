"""An avatar's card says, role by role, where the avatar is further from its person than they
vary, and reads whole at a laptop's 1280 px (issues 38.3 and 39.3)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from mirror_avatar.cli import main
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.generator import IMSGenerator
from mirror_avatar.training.avatar import load_avatar
from mirror_avatar.trial_io import write_csv_trial
from mirror_avatar.trials import make_trial

WIDTH = 1280
SPEED_UP = 1.4
"""How much faster than the person the partners move: a follower that follows them moves about
4 times further from the person than the person's own trials are from one another."""


def sped_up(label: str):
    """A bundled trial played SPEED_UP times faster (its velocities SPEED_UP times larger)."""
    trial = next(t for t in load_zhai2017() if t.label == label)
    return make_trial(trial.times / SPEED_UP, trial.positions, label=f"{label} x{SPEED_UP:g}")


@pytest.fixture(scope="module")
def card(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The avatar of a person of the bundled slow style (three real trials), trained with
    partners that move as the same style sped up: a follower wrong on purpose."""
    folder = tmp_path_factory.mktemp("card")
    (folder / "trials").mkdir()
    for trial in load_zhai2017()[9:12]:
        write_csv_trial(trial, folder / "trials" / f"{trial.label}.csv")
    partners = []
    for name, labels in (("quick-a", ("slow-4", "slow-5", "slow-6")),
                         ("quick-b", ("slow-7", "slow-8", "slow-9"))):  # fmt: skip
        path = folder / f"{name}.npz"
        IMSGenerator(n_symbols=32, random_state=0).fit([sped_up(k) for k in labels]).save(path)
        partners.append(str(path))
    out = folder / "S01.npz"
    status = main(["avatar", "create", str(folder / "trials"), "--name", "S01", "--partners",
                   ",".join(partners), "--sessions", "60", "--jobs", "1",
                   "--out", str(out)])  # fmt: skip
    assert status == 0
    return out


def test_the_card_flags_a_follower_far_from_its_person(card: Path) -> None:
    held = load_avatar(card).summary["proof"]["held_out"]
    assert held["folds"] == [["slow-1"], ["slow-2"], ["slow-3"]]
    assert held["scheme"] == "leave-one-out over 3 trials: 3 avatars, each built without one"
    follower = held["roles"]["follower"]
    assert follower["flagged"] and follower["ratio_to_own"] > 3
    assert follower["emd_to_held_out"] > held["own_emd_range"][1]
    assert set(held["roles"]) == {"follower", "leader", "group member"}
    verdict = load_avatar(card).summary["verdict"]
    assert verdict.startswith("The avatar moves ") and "FLAGGED" in verdict
    assert f"follower ({follower['ratio_to_own']:.1f} x)" in verdict
    page = card.with_suffix(".html").read_text()
    lead = page.index('<p class="lead">')
    assert page.index(verdict.replace("'", "&#39;")) > lead  # the verdict leads the page
    sentences = [held["roles"][role]["verdict"] for role in ("follower", "leader", "group member")]
    assert sentences[0].startswith("As follower, FLAGGED")
    for sentence in sentences:
        assert sentence.replace("'", "&#39;") in page
    assert "FLAGGED: above the person&#39;s own 95th percentile" in page
    assert "EMD P5" not in page and "EMD P95" not in page


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
