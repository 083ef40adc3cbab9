"""Progress on long work, on standard error: a tqdm bar on a terminal, plain lines off one.

Every loop that can run for more than a few seconds (training sessions, played sessions,
generator fits of a sweep or a cross-validation, trials read from a folder) counts its steps on
a `progress_bar`. Off a terminal (a pipe, a file, a test) a bar redrawn in place would fill a log
with carriage returns, so `ProgressLines` writes one plain line at each tenth of the work
instead (``training: 3/12 sessions (25 %), 00:45 elapsed, about 02:15 left``). A terminal that
reports no size (a bare pseudo-terminal) is taken as `FALLBACK_SIZE`: tqdm would draw nothing on
a screen of no lines.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Self, TypeVar

from tqdm.auto import tqdm

FALLBACK_SIZE = os.terminal_size((80, 24))
"""Columns and lines of a terminal that reports no size."""

LINES = 10
"""Lines of `ProgressLines` over the work: one at each tenth."""

Item = TypeVar("Item")

_SILENCED: ContextVar[bool] = ContextVar("progress_silenced", default=False)
"""Whether `silenced` holds: progress not asked for explicitly is not shown."""


def _size() -> os.terminal_size:
    """Size of the terminal on standard error, or `FALLBACK_SIZE` for what it does not report."""
    try:
        columns, lines = os.get_terminal_size(sys.stderr.fileno())
    except (OSError, ValueError, AttributeError):
        return FALLBACK_SIZE
    return os.terminal_size((columns or FALLBACK_SIZE.columns, lines or FALLBACK_SIZE.lines))


def _on_terminal() -> bool:
    """Whether standard error is a terminal."""
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):  # no standard error, or a closed one
        return False


class ProgressLines:
    """Progress off a terminal: a plain line on standard error at each tenth of the work.

    Each line gives the steps done, the time elapsed and, with a known total, the share done and
    an estimate of the time left; without a total, a line comes at each doubling of the count.

    Parameters
    ----------
    total
        Steps of the work, or None when unknown.
    what
        What is counted, leading each line.
    unit
        One step's name (a line says ``unit`` s).
    """

    def __init__(self, total: int | None, what: str, unit: str) -> None:
        self.total = total if total else None
        self.what = what or "progress"
        self.unit = unit
        self.done = 0
        self.start = time.monotonic()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exception: object) -> None:
        return None

    def update(self, n: int = 1) -> None:
        """Count ``n`` steps more, with a line when they reach the next tenth of the work."""
        before, self.done = self.done, self.done + n
        if self._stage(self.done) > self._stage(before) and sys.stderr is not None:
            print(self.line(), file=sys.stderr, flush=True)

    def _stage(self, done: int) -> int:
        """Tenths of the work ``done`` steps make (the count's bit length without a total)."""
        return done.bit_length() if self.total is None else LINES * done // self.total

    def line(self) -> str:
        """Return the line of the steps done so far."""
        elapsed = time.monotonic() - self.start
        said = f"{self.what}: {self.done}"
        if self.total is None:
            plural = "s" if self.done > 1 else ""
            return f"{said} {self.unit}{plural}, {tqdm.format_interval(elapsed)} elapsed"
        left = elapsed * max(self.total - self.done, 0) / self.done
        return (
            f"{said}/{self.total} {self.unit}s ({100 * self.done // self.total} %), "
            f"{tqdm.format_interval(elapsed)} elapsed, about {tqdm.format_interval(left)} left"
        )


@contextmanager
def silenced() -> Iterator[None]:
    """Show no progress in the block unless asked (``enabled=True``).

    For work that is not the user's, such as the kernels' warm-up (`mirror_avatar.warm_up`).
    """
    token = _SILENCED.set(True)
    try:
        yield
    finally:
        _SILENCED.reset(token)


def progress_bar(
    total: int | None = None, what: str = "", unit: str = "step", enabled: bool | None = None
) -> tqdm | ProgressLines:
    """Make a progress bar of ``total`` ``unit`` s, labelled ``what``, on standard error.

    ``enabled``: True (a tqdm bar), False (nothing), or None: a tqdm bar on a terminal, showing
    the steps done, the rate and the time left, `ProgressLines` off one, nothing in `silenced`.
    """
    if enabled is None and _SILENCED.get():
        enabled = False
    if enabled is None and not _on_terminal():
        return ProgressLines(total, what, unit)
    return tqdm(
        total=total,
        desc=what or None,
        unit=unit,
        disable=enabled is False,
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
