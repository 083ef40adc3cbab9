"""Clock stamps read as text: offsets from the first stamp, exact where float64 stamps are not."""

from __future__ import annotations

from decimal import Decimal

import numpy as np
import pandas as pd
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.importing import GAP_TOLERANCE, clock_offsets, fill_gaps


def decimal_offsets(cells: list[str]) -> list[float]:
    """The reference: each stamp minus the first, in exact decimal arithmetic, then rounded."""
    stamps = [Decimal(cell) for cell in cells]
    return [float(stamp - stamps[0]) for stamp in stamps]


@pytest.mark.parametrize(
    "cells",
    [
        [f"1764000000.{k}" for k in range(10)],
        ["1764000000123", "1764000000223", "1764000000323.5"],
        ["-0.5", "0.25", ".75", "-.25", "+1.5", "3"],
        ["1.7e9", "1.7000000001e9"],
    ],
)
def test_offsets_match_exact_decimal_arithmetic(cells: list[str]) -> None:
    offsets = clock_offsets(pd.Series(cells))
    if "e9" in cells[0]:  # exponent notation: parsed as numbers, within a clock's rounding
        np.testing.assert_allclose(offsets, decimal_offsets(cells), rtol=0, atol=GAP_TOLERANCE)
    else:
        assert list(offsets) == decimal_offsets(cells)  # to the last bit


def test_missing_stamps_stay_missing_and_do_not_move_the_origin() -> None:
    offsets = clock_offsets(pd.Series(["", "n/a", "1764000000.5", "", "1764000000.8"]))
    assert np.isnan(offsets[[0, 1, 3]]).all()
    assert offsets[2] == 0.0 and offsets[4] == pytest.approx(0.3, abs=1e-15)


def test_a_gap_is_the_time_between_the_positions_around_it() -> None:
    """Two missing samples at 10 Hz: 0.3 s between their neighbours, interpolated at 0.3 s
    (within `GAP_TOLERANCE` of clock rounding) and refused at 0.29 s."""
    times = np.arange(30) / 10 + 1e-7  # float rounding as an epoch clock leaves it
    positions = np.sin(times)
    positions[[10, 11]] = np.nan
    _, filled, count = fill_gaps(times, positions, 0.3, "trial.csv")
    assert count == 2 and np.isfinite(filled).all()
    assert GAP_TOLERANCE < 0.01
    with pytest.raises(InputError, match=r"between t = 0\.900 s and 1\.200 s \(0\.3 s"):
        fill_gaps(times, positions, 0.29, "trial.csv")
