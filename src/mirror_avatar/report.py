"""The report a researcher reads: sections of text, tables and figures, as HTML and JSON.

Each experiment returns a `Section`; `write_report` assembles sections into one self-contained
``report.html`` (figures embedded as PNG) and a ``metrics.json`` holding every section's numbers.
"""

from __future__ import annotations

import base64
import io
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jinja2
import pandas as pd
from matplotlib.figure import Figure

from mirror_avatar.atomic import json_text, write_atomic_files


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
    tables
        Captioned tables, caption -> DataFrame.
    figures
        Captioned figures, caption -> matplotlib Figure (closed after rendering).
    metrics
        JSON-serialisable numbers for ``metrics.json``.
    """

    key: str
    title: str
    text: list[str] = field(default_factory=list)
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    figures: dict[str, Figure] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)


REPORT_FILES = ("metrics.json", "report.html")
"""The files `write_report` writes in its folder."""


def write_report(
    sections: Sequence[Section],
    out_dir: str | os.PathLike[str],
    title: str = "mirror-avatar report",
    metadata: Mapping[str, Any] | None = None,
) -> Path:
    """Write ``out_dir/report.html`` and ``out_dir/metrics.json``.

    The HTML is self-contained (figures embedded as base64 PNG, tables as HTML, all text
    escaped); ``metrics.json`` holds ``{section.key: section.metrics, ..., "metadata": metadata}``,
    with NaN and infinities written as ``null``. Both files are written together, atomically
    (`mirror_avatar.atomic.write_atomic_files`): a failure leaves neither half-written nor one
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
        What the run was (version, seed, date, command, wall time...), shown at the top of the
        report and stored in ``metrics.json``; JSON-serialisable.

    Returns
    -------
    pathlib.Path
        Path of ``report.html``.
    """
    texts = report_texts(sections, title, metadata)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_atomic_files(out, texts)
    return out / REPORT_FILES[1]


def report_texts(
    sections: Sequence[Section], title: str, metadata: Mapping[str, Any] | None = None,
    lead: str = "",
) -> dict[str, str]:  # fmt: skip
    """Render the files of a report (`REPORT_FILES`), name -> text, without writing them.

    A command that writes other files with its report writes them all together
    (`mirror_avatar.atomic.write_atomic_files`); ``lead`` is the report's verdict
    (`render_report`).
    """
    keys = [section.key for section in sections]
    if len(set(keys)) != len(keys) or "metadata" in keys:
        raise ValueError(f"section keys must be distinct and not 'metadata', got {keys}")
    metadata = dict(metadata or {})
    metrics = {s.key: s.metrics for s in sections} | {"metadata": metadata}
    metrics_name, report_name = REPORT_FILES
    return {
        metrics_name: json_text(metrics),
        report_name: render_report(sections, title, metadata, lead),
    }


def render_report(
    sections: Sequence[Section],
    title: str,
    metadata: Mapping[str, Any] | None = None,
    lead: str = "",
) -> str:
    """Render sections as one self-contained HTML page (see `write_report`).

    ``lead``, when given, is the line shown first under the title (a report's verdict).
    """
    return _template().render(
        title=title,
        lead=lead,
        metadata=dict(metadata or {}),
        sections=[_render_section(section) for section in sections],
    )


def p_text(p: float, n_surrogates: int) -> str:
    """Write a p-value against ``n_surrogates`` surrogates as a report's prose says it.

    With ``m`` surrogates the smallest p-value is ``1 / (m + 1)``
    (`mirror_avatar.metrics.surrogates.p_value`): there the surrogates bound it from above
    only, written ``p <= 0.01`` (99 surrogates), never ``p = 0.01``. NaN (no finite
    surrogate, or nothing to test) is ``no p-value``.
    """
    if not math.isfinite(p):
        return "no p-value"
    floor = 1.0 / (n_surrogates + 1)
    if p <= floor * (1 + 1e-9):
        return f"p <= {floor:.3g}"
    return f"p = {p:.3g}"


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
        "tables": [
            (caption, table.to_html(float_format=_format_float, border=0, na_rep="-"))
            for caption, table in section.tables.items()
        ],
        "figures": [
            (caption, base64.b64encode(render_png(figure)).decode("ascii"))
            for caption, figure in section.figures.items()
        ],
    }


def _format_float(value: float) -> str:
    return f"{value:.4g}"


def _template() -> jinja2.Template:
    environment = jinja2.Environment(
        loader=jinja2.PackageLoader("mirror_avatar", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
    )
    return environment.get_template("report.html.j2")
