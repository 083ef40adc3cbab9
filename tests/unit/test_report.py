import base64
import json
import re

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from mirror_avatar.report import Section, render_png, render_report, write_report


def small_figure():
    figure = Figure()
    figure.add_subplot().plot([0, 1], [1, 0])
    return figure


def test_write_report_html_and_metrics(tmp_path):
    figure = small_figure()
    section = Section(
        key="demo",
        title="Demo <section>",
        text=["a < b & <script>alert(1)</script>"],
        tables={"numbers": pd.DataFrame({"x": [1.5, np.nan]}, index=["a", "b"])},
        figures={"a line": figure},
        metrics={"value": np.float64(0.25), "missing": float("nan"), "array": np.arange(3)},
    )
    path = write_report([section], tmp_path / "out", title="T", metadata={"seed": 7})
    assert path == tmp_path / "out" / "report.html"
    html = path.read_text()
    assert "<script>" not in html and "&lt;script&gt;" in html
    assert "Demo &lt;section&gt;" in html
    assert "<td>1.5</td>" in html
    encoded = re.search(r'data:image/png;base64,([A-Za-z0-9+/=]+)"', html).group(1)
    assert base64.b64decode(encoded).startswith(b"\x89PNG")
    assert figure.axes == []
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics == {
        "demo": {"value": 0.25, "missing": None, "array": [0, 1, 2]},
        "metadata": {"seed": 7},
    }
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["metrics.json", "report.html"]


def test_write_report_rejects_duplicate_keys(tmp_path):
    with pytest.raises(ValueError, match="distinct"):
        write_report([Section("a", "A"), Section("a", "B")], tmp_path)
    assert not (tmp_path / "report.html").exists()


def test_render_png_is_a_png():
    assert render_png(small_figure()).startswith(b"\x89PNG")


def test_a_mapping_in_the_metadata_is_a_table(tmp_path):
    """Timings by experiment read as rows, not as a Python dict."""
    timings = {"signature": 12.5, "virtual trainer": 3.25}
    path = write_report([Section("a", "A")], tmp_path, "T", {"experiment_time_s": timings})
    html = path.read_text()
    assert "{&#39;" not in html and "{'" not in html
    rows = re.findall(r"<tr><th>([^<]*)</th><td>([^<]*)</td></tr>", html)
    assert rows == [("signature", "12.5"), ("virtual trainer", "3.25")]


def test_a_lead_is_the_first_line_under_the_title():
    page = render_report([Section("s", "S")], "T", {"seed": 1}, lead="Verdict <1>")
    lead = page.index('<p class="lead">Verdict &lt;1&gt;</p>')
    assert page.index("</h1>") < lead < page.index('<dl class="meta">')
    assert 'class="lead"' not in render_report([Section("s", "S")], "T")


def test_the_verdicts_come_before_what_the_run_was(tmp_path):
    """Issue 39.3: a report leads with its answers; the run's details follow them."""
    sections = [Section("a", "A", text=["details"], verdict="told apart"), Section("b", "B")]
    path = write_report(sections, tmp_path, "T", {"seed": 1, "quick": True}, lead="Answer",
                        json_only=("quick",))  # fmt: skip
    page = path.read_text()
    lead, contents = page.index("Answer"), page.index('<span class="verdict">told apart</span>')
    assert lead < contents < page.index('<dl class="meta">')
    section = page.index('<section id="a">')
    assert section < page.index('<p class="verdict">told apart</p>') < page.index("details")
    assert "<dt>quick</dt>" not in page and "<dt>seed</dt>" in page
    metadata = json.loads((tmp_path / "metrics.json").read_text())["metadata"]
    assert metadata == {"seed": 1, "quick": True}


def test_wide_tables_are_set_small_and_their_names_break_after_underscores():
    wide = pd.DataFrame(np.ones((2, 10)), columns=[f"generated_velocity_{k}" for k in range(10)])
    narrow = pd.DataFrame({"n_strokes": [1]})
    page = render_report([Section("s", "S", tables={"wide": wide, "narrow": narrow})], "T")
    assert page.count('class="dataframe wide"') == 1
    assert "<th>generated_<wbr>velocity_<wbr>0</th>" in page and "n_<wbr>strokes" in page


def test_a_figure_already_rendered_is_embedded_as_it_is():
    png = render_png(small_figure())
    page = render_report([Section("s", "S", figures={"done": png})], "T")
    assert base64.b64encode(png).decode("ascii") in page
