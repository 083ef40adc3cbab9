"""The report a researcher reads: sections of text, tables and figures, as HTML and JSON.

Each experiment returns a `Section`; `write_report` assembles sections into one self-contained
``report.html`` (figures embedded as PNG) and a ``metrics.json`` holding every section's numbers.
"""

from __future__ import annotations

import base64
import io
import os
import re
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jinja2
import pandas as pd
from matplotlib.figure import Figure

from mirror_avatar.files.atomic import json_text, write_atomic_files


@dataclass
class Section:
    """One part of the report.

    Parameters
    ----------
    key
        Short identifier, the section's key in ``metrics.json`` (for instance ``"signature"``).
    title
        Heading shown in the report.
    text
        Paragraphs of plain text (no HTML), shown before the tables and figures.
    verdict
        The section's answer in one line of plain text, shown first in the section and beside
        its entry in the report's contents (empty: none).
    tables
        Captioned tables, caption -> DataFrame.
    figures
        Captioned figures, caption -> matplotlib Figure (closed after rendering) or the PNG
        bytes of one already rendered (a figure also written to its own file).
    metrics
        JSON-serialisable numbers for ``metrics.json``.
    """

    key: str
    title: str
    text: list[str] = field(default_factory=list)
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    figures: Mapping[str, Figure | bytes] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)
    verdict: str = ""


REPORT_FILES = ("metrics.json", "report.html")
"""The files `write_report` writes in its folder."""


def write_report(
    sections: Sequence[Section],
    out_dir: str | os.PathLike[str],
    title: str = "mirror-avatar report",
    metadata: Mapping[str, Any] | None = None,
    lead: str = "",
    json_only: Collection[str] = (),
) -> Path:
    """Write ``out_dir/report.html`` and ``out_dir/metrics.json``.

    The HTML is self-contained (figures embedded as base64 PNG, tables as HTML, all text
    escaped); ``metrics.json`` holds ``{section.key: section.metrics, ..., "metadata": metadata}``,
    with NaN and infinities written as ``null``. Both files are written together, atomically
    (`mirror_avatar.files.atomic.write_atomic_files`): a failure leaves neither half-written nor one
    without the other. Every figure is closed once rendered.

    Parameters
    ----------
    sections
        The report's sections, in order; keys must be distinct.
    out_dir
        Output directory, created if missing.
    title
        Report title.
    metadata
        What the run was (version, seed, date, command, wall time...), shown under the report's
        contents and stored in ``metrics.json``; JSON-serialisable.
    lead
        The report's verdict, shown first under the title (see `render_report`).
    json_only
        Keys of ``metadata`` stored in ``metrics.json`` but not shown in the HTML (values that
        the lead or another entry already says in words).

    Returns
    -------
    pathlib.Path
        Path of ``report.html``.
    """
    texts = report_texts(sections, title, metadata, lead, json_only)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_atomic_files(out, texts)
    return out / REPORT_FILES[1]


def report_texts(
    sections: Sequence[Section],
    title: str,
    metadata: Mapping[str, Any] | None = None,
    lead: str = "",
    json_only: Collection[str] = (),
) -> dict[str, str]:
    """Render the files of a report (`REPORT_FILES`), name -> text, without writing them.

    A command that writes other files with its report writes them all together
    (`mirror_avatar.files.atomic.write_atomic_files`). ``lead`` and ``json_only`` are as in
    `write_report`.
    """
    keys = [section.key for section in sections]
    if len(set(keys)) != len(keys) or "metadata" in keys:
        raise ValueError(f"section keys must be distinct and not 'metadata', got {keys}")
    metadata = dict(metadata or {})
    metrics = {s.key: s.metrics for s in sections} | {"metadata": metadata}
    metrics_name, report_name = REPORT_FILES
    shown = {name: value for name, value in metadata.items() if name not in json_only}
    return {
        metrics_name: json_text(metrics),
        report_name: render_report(sections, title, shown, lead),
    }


def render_report(
    sections: Sequence[Section],
    title: str,
    metadata: Mapping[str, Any] | None = None,
    lead: str = "",
) -> str:
    """Render sections as one self-contained HTML page (see `write_report`).

    The page leads with its answer: the title, then ``lead`` when given (the report's verdict),
    then the contents with each section's verdict, then ``metadata`` (what the run was). Its
    text column stays narrow enough to read; tables and figures use the window's width up to
    1200 px, a table wider than that scrolls inside its own box, and column names break after
    their underscores, so that the page itself never scrolls sideways.
    """
    return _template().render(
        title=title,
        lead=lead,
        metadata=dict(metadata or {}),
        sections=[_render_section(section) for section in sections],
    )


def render_png(figure: Figure, dpi: int = 110) -> bytes:
    """Render a figure to PNG bytes (Agg), then clear it to release its memory."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    figure.clear()
    return buffer.getvalue()


def _render_section(section: Section) -> dict[str, Any]:
    return {
        "key": section.key,
        "title": section.title,
        "text": section.text,
        "verdict": section.verdict,
        "tables": [(caption, _table_html(table)) for caption, table in section.tables.items()],
        "figures": [
            (caption, base64.b64encode(_png(figure)).decode("ascii"))
            for caption, figure in section.figures.items()
        ],
    }


def _png(figure: Figure | bytes) -> bytes:
    return figure if isinstance(figure, bytes) else render_png(figure)


WIDE_TABLE = 10
"""Columns (index levels included) above which a table is set in smaller type (class ``wide``)."""


def _table_html(table: pd.DataFrame) -> str:
    """Render the table as HTML, its headers breakable after each underscore (``<wbr>``)."""
    wide = table.shape[1] + table.index.nlevels > WIDE_TABLE
    html = table.to_html(
        float_format=_format_float, border=0, na_rep="-", classes="wide" if wide else None
    )
    return _HEADER.sub(lambda m: m[1] + m[2].replace("_", "_<wbr>") + m[3], html)


_HEADER = re.compile(r"(<th[^>]*>)([^<]*)(</th>)")
"""A header cell of pandas' HTML; its text is escaped, so it holds no ``<``."""


def _format_float(value: float) -> str:
    return f"{value:.4g}"


def _template() -> jinja2.Template:
    environment = jinja2.Environment(
        loader=jinja2.PackageLoader("mirror_avatar", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
    )
    return environment.get_template("report.html.j2")
