"""Reading the TSV tables of a BIDS dataset: those an export merges into, and its answers.

``participants.tsv`` and ``sub-<label>_scans.tsv`` gain rows with each export; the rows already
there are read back by their key column and kept, with their columns.
"""

from __future__ import annotations

from pathlib import Path

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.bids.writing import cell_text
from mirror_avatar.files.trial_io import read_sidecar_text


def read_tsv(path: Path, key: str) -> tuple[list[str], dict[str, dict[str, str]]]:
    """Read a TSV table with a header: its columns and its rows by their ``key`` cell.

    Returns empty columns and rows when the file does not exist.

    Raises
    ------
    InputError
        No ``key`` column, or as `tsv_rows`.
    """
    if not path.is_file():
        return [], {}
    header, rows = tsv_rows(path)
    if key not in header:
        raise InputError(path, f"no {key} column")
    return header, {row[key]: row for row in rows}


def tsv_rows(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    """Read a TSV table with a header: its columns and its rows, each cell's text as written.

    Rows end at line feeds (a carriage return before one is dropped), cells at tabs, and a
    cell's escapes are read back (`mirror_avatar.files.bids.writing.cell_text`); quotes are
    text, as BIDS has them. Blank lines are skipped.

    Raises
    ------
    InputError
        As `mirror_avatar.files.trial_io.read_sidecar_text`, or a row whose cells do not match
        the header.
    """
    lines = [line.removesuffix("\r") for line in read_sidecar_text(path).split("\n")]
    lines = [line for line in lines if line.strip()]
    header = lines[0].split("\t") if lines else []
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        cells = line.split("\t")
        if len(cells) != len(header):
            raise InputError(path, f"row {number} has {len(cells)} cells for {len(header)} columns")
        rows.append(dict(zip(header, map(cell_text, cells), strict=True)))
    return header, rows
