"""The report a researcher reads: sections of text, tables and figures, as HTML and JSON.

Each experiment returns a `Section`; `write_report` assembles sections into one self-contained
``report.html`` (figures embedded as PNG) and a ``metrics.json`` holding every section's numbers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import pandas as pd
from matplotlib.figure import Figure


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
