"""The demo report and the signature report in Chromium at 1280 px (issue 39.3).

Each page must be no wider than the window, no table cut off in its own box, and its verdict
must come first; the screenshots are saved in the test's temporary folder, to be looked at.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from mirror_avatar.cli import main
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.trial_io import write_csv_trial

pytestmark = pytest.mark.browser

WIDTH = 1280


@pytest.fixture(scope="module")
def demo_report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``make demo``'s report at its quickest (``reproduce --quick``, as test_reproduce runs it)."""
    out = tmp_path_factory.mktemp("demo") / "report"
    assert main(["reproduce", "--quick", "--out", str(out)]) == 0
    return out / "report.html"


@pytest.fixture(scope="module")
def signature_report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Seven people (the bundled trials, 2 or 3 each, in a folder each) in two groups."""
    root = tmp_path_factory.mktemp("signature")
    rows = ["person,group"]
    for trial in load_zhai2017():
        k = int(trial.label.split("-")[1])
        number = min((k - 1) // 2, 3) + 1 if trial.group == "fast" else (k - 1) // 3 + 1
        person = f"{trial.group}_participant_{number}"
        (root / "people" / person).mkdir(parents=True, exist_ok=True)
        write_csv_trial(trial, root / "people" / person / f"{trial.label}.csv")
        rows.append(f"{person},{trial.group}")
    groups = root / "groups.csv"
    groups.write_text("\n".join(dict.fromkeys(rows)) + "\n")
    out = root / "out"
    arguments = ["signature", str(root / "people"), "--groups", str(groups), "--out", str(out)]
    assert main(arguments) == 0
    return out / "report.html"


def open_at_1280(chromium: Any, report: Path) -> Any:
    page = chromium.new_page(viewport={"width": WIDTH, "height": 900})
    page.goto(report.as_uri())
    return page


def assert_fits(page: Any) -> None:
    """The page no wider than the window, and nothing inside it cut off on the right."""
    assert page.evaluate("document.documentElement.scrollWidth") <= WIDTH
    cut = page.evaluate(
        """Array.from(document.querySelectorAll('figure.table'))
             .filter(f => f.scrollWidth > f.clientWidth)
             .map(f => f.querySelector('figcaption').textContent)"""
    )
    assert cut == []
    for element in page.locator("main img, main table").all():
        box = element.bounding_box()
        assert box is not None and box["x"] + box["width"] <= WIDTH


@pytest.mark.long
def test_the_demo_report_fits_1280_px_and_leads_with_its_verdicts(
    chromium: Any, demo_report: Path, tmp_path: Path
) -> None:
    page = open_at_1280(chromium, demo_report)
    assert_fits(page)
    first = page.locator("main > p.lead").inner_text()
    assert first.startswith("A quick run (--quick)")
    verdicts = page.locator("nav span.verdict").all_inner_texts()
    assert len(verdicts) == 7 and verdicts[0].startswith("the 2 groups are told apart")
    assert "quick" not in page.locator("dl.meta dt").all_inner_texts()
    page.screenshot(path=str(tmp_path / "demo-report-1280.png"), full_page=True)
    page.close()


def test_the_signature_report_fits_1280_px_and_leads_with_its_verdict(
    chromium: Any, signature_report: Path, tmp_path: Path
) -> None:
    page = open_at_1280(chromium, signature_report)
    assert_fits(page)
    lead = page.locator("main > p.lead").inner_text()
    assert lead.startswith("The 7 people are told apart:") and "Groups: fast (4 people)" in lead
    assert page.locator("section#people img").count() == 2
    page.screenshot(path=str(tmp_path / "signature-report-1280.png"), full_page=True)
    page.close()
