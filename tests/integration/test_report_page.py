"""The HTML report in Chromium at a laptop's width: nothing makes the page scroll sideways."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from browsers import SCREENSHOTS

from mirror_avatar.report import Section, write_report

WIDTH = 1280


def wide_section() -> Section:
    """A section like the generator's stroke table: many long column names, a long path."""
    columns = [f"generated_{name}_{stat}" for name in ("skewness", "kurtosis", "velocity_rms",
               "acceleration_rms") for stat in ("mean", "sd")]  # fmt: skip
    table = pd.DataFrame(np.random.default_rng(0).random((2, len(columns))), columns=columns,
                         index=["fast", "slow"])  # fmt: skip
    figure, axes = plt.subplots(figsize=(8, 3))
    axes.plot([0, 1], [0, 1])
    path = "/data/" + "very_long_folder_name_" * 12 + "trial.csv"
    return Section(
        key="wide",
        title="A wide table",
        text=[f"Read from {path}."],
        tables={
            "Velocity strokes, human against generated": table,
            "Far too many columns": pd.DataFrame(
                np.ones((1, 60)), columns=[f"column {k}" for k in range(60)]
            ),
        },
        figures={"A line": figure},
    )


def test_the_report_does_not_scroll_sideways_at_1280_px(chromium: Any, tmp_path: Path) -> None:
    report = write_report([wide_section()], tmp_path, metadata={"command": "x " * 200})
    page = chromium.new_page(viewport={"width": WIDTH, "height": 800})
    page.goto(report.as_uri())
    assert page.evaluate("document.documentElement.scrollWidth") == WIDTH
    stroke_table, huge_table = page.locator("figure.table").all()
    for table in (stroke_table, huge_table):
        box = table.bounding_box()
        assert box is not None and box["x"] + box["width"] <= WIDTH
    # the names break after their underscores, so the stroke table fits whole (issue 39.3);
    # a table that cannot fit scrolls in its own box
    assert stroke_table.evaluate("f => f.scrollWidth <= f.clientWidth")
    assert huge_table.evaluate("f => f.scrollWidth > f.clientWidth")
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SCREENSHOTS / "report-1280.png"), full_page=True)
    page.close()
