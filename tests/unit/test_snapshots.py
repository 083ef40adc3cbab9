"""The snapshot tests' comparison: numbers to rounding, everything else exactly."""

from __future__ import annotations

import numpy as np
import pytest

from snapshots import LAST_DIGIT, assert_close, perturbed, read_snapshot, write_snapshot

DOCUMENT = {
    "trim": 1.0,
    "session": {"rmse": 0.16115002166123926, "leader": 0, "label": "P1", "missing": None},
    "rows": [["time", "x_0"], ["0.02", "-0.123456"], ["-1", "nan"]],
    "flags": [True, False],
}
"""A JSON-like document with floats, integers, float and integer text, None and booleans."""


def test_every_number_moved_by_its_last_digit_is_close() -> None:
    moved = perturbed(DOCUMENT, LAST_DIGIT)
    rmse = DOCUMENT["session"]["rmse"]
    assert 1 <= (moved["session"]["rmse"] - rmse) / np.spacing(rmse) <= 4  # units in the last place
    assert moved["rows"][1] == ["0.02000000000000001", "-0.12345600000000005"]
    assert moved["rows"][2] == ["-1", "nan"] and moved["session"]["leader"] == 0
    assert_close(moved, DOCUMENT)


@pytest.mark.parametrize(
    "change",
    [
        lambda d: d["session"].update(rmse=d["session"]["rmse"] * (1 + 1e-6)),
        lambda d: d["rows"][1].__setitem__(1, "-0.1234561"),
        lambda d: d["rows"][2].__setitem__(0, "-2"),
        lambda d: d["session"].update(leader=1),
        lambda d: d["session"].update(label="P2"),
        lambda d: d["session"].pop("missing"),
        lambda d: d["session"].update(extra=1),
        lambda d: d.update(trim=1e-11),
        lambda d: d["flags"].append(True),
        lambda d: d["flags"].__setitem__(0, 1),
        lambda d: d.update(session=[]),
    ],
    ids=["float", "float text", "integer text", "integer", "text", "key missing",
         "key added", "near zero", "length", "bool to int", "structure"],
)  # fmt: skip
def test_any_other_change_fails_naming_its_place(change) -> None:
    changed = perturbed(DOCUMENT, 1.0)
    change(changed)
    with pytest.raises(AssertionError):
        assert_close(changed, DOCUMENT)


def test_an_integer_and_a_float_compare_as_numbers() -> None:
    assert_close({"duration": 2.0, "n": 3}, {"duration": 2, "n": 3.0000000000000004})
    with pytest.raises(AssertionError):
        assert_close(2.000001, 2)


def test_keys_in_another_order_fail() -> None:
    with pytest.raises(AssertionError, match="keys"):
        assert_close({"b": 1, "a": 2}, {"a": 2, "b": 1})


def test_a_float_array_is_compared_to_rounding() -> None:
    array = np.array([[0.5, -3.25e-3], [0.0, 12.0]])
    assert_close(perturbed(array, LAST_DIGIT), array)
    with pytest.raises(AssertionError):
        assert_close(perturbed(array, 1.0 + 1e-6), array)


def test_an_integer_array_is_compared_exactly() -> None:
    seeds = np.array([2**63 + 1, 7], dtype=np.uint64)
    assert_close(seeds.copy(), seeds)
    with pytest.raises(AssertionError):
        assert_close(seeds + np.uint64(1), seeds)


@pytest.mark.parametrize("suffix", [".json", ".csv", ".tsv", ".npz"])
def test_a_fixture_written_reads_back_as_it_was(tmp_path, suffix) -> None:
    value = {
        ".json": DOCUMENT,
        ".csv": DOCUMENT["rows"],
        ".tsv": [["a b", "0.5"], ["1", ""]],
        ".npz": {"x": np.linspace(0.0, 1.0, 7), "seeds": np.arange(3, dtype=np.uint64)},
    }[suffix]
    path = tmp_path / f"fixture{suffix}"
    write_snapshot(path, value)
    read = read_snapshot(path)
    if suffix == ".npz":
        assert read.keys() == value.keys()
        for name, array in value.items():
            np.testing.assert_array_equal(read[name], array)
            assert read[name].dtype == array.dtype
    else:
        assert read == value
