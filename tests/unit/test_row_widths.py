"""Ragged rows of CSV and TSV files: found in blocks, as a line-by-line count finds them."""

from __future__ import annotations

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.files import row_widths
from mirror_avatar.files.bids.reading import read_bids_motion
from mirror_avatar.files.row_widths import ragged_line
from mirror_avatar.files.trial_io import _first_row, _first_width, read_csv_trial

LIMIT = 2**20


def line_by_line(text: str, sep: str, width: int) -> tuple[int, int] | None:
    """The reference: split the text into lines and count each one's cells."""
    lines = text.split("\n")
    ended = text.endswith("\n")
    if ended:
        lines = lines[:-1]
    first = next(k for k, line in enumerate(lines) if line.strip(" \r"))
    for k in range(first + 1, len(lines)):
        line = lines[k]
        if not line.strip(" \r"):
            continue
        cells = line.count(sep) + 1
        last_cut = k == len(lines) - 1 and not ended
        if cells > width or (cells < width and not last_cut):
            return k + 1, cells
    return None


def random_table(rng: np.random.Generator, sep: str, width: int) -> str:
    rows = []
    for _ in range(rng.integers(1, 60)):
        kind = rng.random()
        if kind < 0.05:
            rows.append(" \r" * int(rng.integers(0, 2)))  # blank
            continue
        cells = width + (int(rng.integers(-1, 2)) if kind < 0.1 else 0)
        rows.append(sep.join(f"{rng.normal():.3f}" for _ in range(max(1, cells))))
    ending = "\n" if rng.random() < 0.7 else ""
    return sep.join(f"c{k}" for k in range(width)) + "\n" + "\n".join(rows) + ending


@pytest.mark.parametrize("block", [1, 7, 64, row_widths.BLOCK_BYTES])
def test_the_first_ragged_line_is_the_one_a_line_by_line_count_finds(tmp_path, monkeypatch, block):
    monkeypatch.setattr(row_widths, "BLOCK_BYTES", block)
    rng = np.random.default_rng(block)
    path = tmp_path / "table.tsv"
    for trial in range(200):
        sep = "\t" if trial % 2 else ","
        width = int(rng.integers(1, 4))
        text = random_table(rng, sep, width)
        path.write_text(text)
        assert ragged_line(path, sep, width, LIMIT) == line_by_line(text, sep, width), text


def test_quoted_cells_are_counted_as_cells(tmp_path):
    path = tmp_path / "quoted.csv"
    path.write_text('"time, s",position\n0,"0,5"\n1,0.2,9\n')
    assert ragged_line(path, ",", 2, LIMIT) == (3, 3)
    path.write_text('"time, s",position\n0,"0.5"\n1,0.2\n')
    assert ragged_line(path, ",", 2, LIMIT) is None


def test_a_last_line_cut_short_is_missing_samples_not_a_ragged_row(tmp_path):
    path = tmp_path / "cut.csv"
    path.write_text("time,position\n0,0.1\n0.1")
    assert ragged_line(path, ",", 2, LIMIT) is None
    path.write_text("time,position\n0,0.1\n0.1\n")
    assert ragged_line(path, ",", 2, LIMIT) == (3, 1)


def test_a_ragged_csv_trial_is_refused_naming_the_line(tmp_path):
    lines = ["time,position"] + [f"{k / 60:.4f},{0.1 * (k % 7):.3f}" for k in range(100)]
    lines[9] = lines[9].split(",")[0]
    path = tmp_path / "trial.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="line 10 holds 1 value where the columns read need 2"):
        read_csv_trial(path)


def test_a_ragged_motion_tsv_is_refused_naming_the_line(tmp_path):
    rows = [f"{0.3 * np.sin(k / 10):.5f}" for k in range(600)]
    rows[10] += "\t0.5"
    path = tmp_path / "sub-01_task-mirror_motion.tsv"
    path.write_text("\n".join(rows) + "\n")
    (tmp_path / "sub-01_task-mirror_motion.json").write_text('{"SamplingFrequency": 60}')
    with pytest.raises(InputError, match="line 11 holds 2 values where the first row holds 1"):
        read_bids_motion(path)


@pytest.mark.parametrize(
    ("text", "sep"),
    [
        ("t,x,y\n1,2,3\n", ","),
        (" t , x \r\n1,2\r\n", ","),
        ("t,x,\n1,2,\n", ","),
        ("\ufefft,x\n1,2\n", ","),
        ("t\tx\ty\n1\t2\t3\n", "\t"),
        ("t;x\n", ","),
        ('"t,x",y\n1,2\n', ","),
        ("\n  \nt,x,y\n", ","),
        ("t,x\ry,z\r", ","),
    ],
)
def test_the_first_rows_width_is_the_number_of_cells_pandas_reads(tmp_path, text, sep):
    path = tmp_path / "table.csv"
    path.write_text(text, newline="")
    assert _first_width(path, sep) == len(_first_row(path, sep))
