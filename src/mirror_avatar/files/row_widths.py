"""Rows of a delimited text file that hold more or fewer values than they should.

A CSV or TSV reader that picks columns by position (pandas' ``usecols``) fills a short row's
missing cells with NaN and drops a long row's extra cells, so a ragged file reads as if whole.
`ragged_line` finds the first line holding more cells than expected, or fewer, in blocks of
`BLOCK_BYTES`, so memory stays constant whatever the file's size: only the positions of the
separators and line ends are kept, and each line's separators are counted between its ends
(`numpy.searchsorted`).

Blank lines (nothing but spaces and carriage returns) are skipped, as the readers skip them. A
last line without its line end (a recording cut off, e.g. by a crash) may be short: its missing
cells are missing samples. A file whose lines after the first hold a double quote is counted
with the `csv` module instead, which knows quoted cells (slower, but such files are not the
numeric tables the readers expect), every row checked.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from pathlib import Path
from typing import IO

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.files.user_files import open_regular

BLOCK_BYTES = 2**20
"""Bytes read at a time (1 MiB): a few times this is what the check holds in memory."""

NEWLINE, QUOTE, SPACE, RETURN = (ord(c) for c in '\n" \r')


def ragged_line(
    path: Path, sep: str, width: int, max_bytes: int, fewest: int | None = None
) -> tuple[int, int] | None:
    """Return the first line holding more than ``width`` cells or fewer than ``fewest``.

    Parameters
    ----------
    path
        A CSV or TSV file, read as bytes (at most ``max_bytes``; `open_regular` refuses more).
    sep
        The one-character separator (``","`` or a tab).
    width
        The cells every non-blank line must hold: the first non-blank line's (a header's cells
        may be quoted), which is not checked.
    max_bytes
        The size limit passed to `open_regular`.
    fewest
        The fewest cells a line may hold (a header's trailing columns may be left empty);
        ``width`` when None.

    Returns
    -------
    tuple of int or None
        The line's number in the file (from 1, blank lines counted) and its number of cells;
        None when every line holds ``fewest`` to ``width`` cells (a last line without its line
        end may hold fewer).
    """
    span = (width if fewest is None else fewest, width)
    with open_regular(path, max_bytes) as file:
        number = 1
        while (first := file.readline()) and not first.strip(b" \r\n"):
            number += 1
        for lines, complete in _blocks_of_lines(file):
            if np.any(lines == QUOTE):
                return _ragged_quoted(path, sep, span, max_bytes)
            ends = np.flatnonzero(lines == NEWLINE)
            found = _ragged_in(lines, ends, ord(sep), span, complete)
            if found is not None:
                return number + 1 + found[0], found[1]
            number += ends.size
    return None


def _blocks_of_lines(file: IO[bytes]) -> Iterator[tuple[NDArray[np.uint8], bool]]:
    """Yield the file's bytes in whole lines, each block with whether its last line ends."""
    carry = b""
    while block := file.read(BLOCK_BYTES):
        data = carry + block
        end = data.rfind(b"\n") + 1
        carry = data[end:]
        if end:
            yield np.frombuffer(data[:end], dtype=np.uint8), True
    if carry:
        yield np.frombuffer(carry, dtype=np.uint8), False


def _ragged_in(
    lines: NDArray[np.uint8],
    ends: NDArray[np.intp],
    sep: int,
    span: tuple[int, int],
    complete: bool,
) -> tuple[int, int] | None:
    """Return a block's first line outside ``span`` cells (index from 0, cells), or None.

    ``ends`` are the positions of the block's line ends. Only the positions of separators,
    line ends, spaces and carriage returns are kept (a few per line), so the block's bytes
    are not widened.
    """
    if not complete:
        ends = np.append(ends, lines.size)
    starts = np.concatenate(([0], ends[:-1] + 1))
    cells = _count_between(np.flatnonzero(lines == sep), starts, ends) + 1
    blanks = np.flatnonzero((lines == SPACE) | (lines == RETURN))
    filled = _count_between(blanks, starts, ends) < ends - starts
    wrong = filled & ((cells < span[0]) | (cells > span[1]))
    if not complete:
        wrong[-1] = filled[-1] and cells[-1] > span[1]
    bad = np.flatnonzero(wrong)
    return (int(bad[0]), int(cells[bad[0]])) if bad.size else None


def _count_between(
    positions: NDArray[np.intp], starts: NDArray[np.intp], ends: NDArray[np.intp]
) -> NDArray[np.intp]:
    """Count the sorted ``positions`` in each [start, end)."""
    return np.searchsorted(positions, ends) - np.searchsorted(positions, starts)


def _ragged_quoted(
    path: Path, sep: str, span: tuple[int, int], max_bytes: int
) -> tuple[int, int] | None:
    """`ragged_line` for a file with quoted cells, by the `csv` module (every row checked)."""
    with (
        open_regular(path, max_bytes) as file,
        io.TextIOWrapper(file, encoding="utf-8-sig", newline="") as text,
    ):
        reader = csv.reader(text, delimiter=sep)
        for row in reader:
            if any(cell.strip() for cell in row) and not span[0] <= len(row) <= span[1]:
                return reader.line_num, len(row)
    return None
