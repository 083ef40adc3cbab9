"""Reading the TSV tables of a BIDS dataset that an export merges into.

``participants.tsv`` and ``sub-<label>_scans.tsv`` gain rows with each export; the rows already
there are read back by their key column and kept, with their columns.
"""

from __future__ import annotations

from pathlib import Path

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trial_io import read_sidecar_text


def read_tsv(path: Path, key: str) -> tuple[list[str], dict[str, dict[str, str]]]:
    """Read a TSV table with a header: its columns and its rows by their ``key`` cell.

    Returns empty columns and rows when the file does not exist.

    Raises
    ------
    InputError
        No ``key`` column, or a row whose cells do not match the header.
    """
    if not path.is_file():
        return [], {}
    lines = [line for line in read_sidecar_text(path).splitlines() if line.strip()]
    header = lines[0].split("\t") if lines else []
    if key not in header:
        raise InputError(path, f"no {key} column")
    rows: dict[str, dict[str, str]] = {}
    for number, line in enumerate(lines[1:], start=2):
        cells = line.split("\t")
        if len(cells) != len(header):
            raise InputError(path, f"row {number} has {len(cells)} cells for {len(header)} columns")
        row = dict(zip(header, cells, strict=True))
        rows[row[key]] = row
    return header, rows
