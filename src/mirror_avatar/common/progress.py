"""Progress bars on long work: tqdm on standard error, with the time left, only on a terminal.

Every loop that can run for more than a few seconds (training sessions, played sessions,
generator fits of a sweep or a cross-validation, trials read from a folder) counts its steps on
a `progress_bar`. Off a terminal (a pipe, a file, a test) the bar prints nothing. A terminal
that reports no size (a bare pseudo-terminal) is taken as `FALLBACK_SIZE`: tqdm would
draw nothing on a screen of no lines.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

from tqdm.auto import tqdm

FALLBACK_SIZE = os.terminal_size((80, 24))
"""Columns and lines of a terminal that reports no size."""

Item = TypeVar("Item")


def _size() -> os.terminal_size:
    """Size of the terminal on standard error, or `FALLBACK_SIZE` for what it does not report."""
    try:
        columns, lines = os.get_terminal_size(sys.stderr.fileno())
    except (OSError, ValueError, AttributeError):
        return FALLBACK_SIZE
    return os.terminal_size((columns or FALLBACK_SIZE.columns, lines or FALLBACK_SIZE.lines))


def progress_bar(
    total: int | None = None, what: str = "", unit: str = "step", enabled: bool | None = None
) -> tqdm:
    """Make a tqdm bar of ``total`` ``unit`` s, labelled ``what``, on standard error.

    ``enabled``: True, False, or None (only when standard error is a terminal). The bar shows
    the steps done, the rate and the time left.
    """
    return tqdm(
        total=total,
        desc=what or None,
        unit=unit,
        disable=None if enabled is None else not enabled,
        ncols=_size().columns,
        nrows=_size().lines,
        file=sys.stderr,
    )


def counted(
    items: Iterable[Item], total: int, what: str, unit: str = "step", enabled: bool | None = None
) -> Iterator[Item]:
    """Yield ``items`` while a `progress_bar` of ``total`` counts them."""
    with progress_bar(total, what, unit, enabled) as bar:
        for item in items:
            yield item
            bar.update()
