"""Numbers recorded on one machine compared with those computed on another.

A snapshot test pins what the code wrote once (a fixture) and compares what it writes today.
The same code on another CPU, or with another BLAS or NumPy build, rounds differently (fused
multiply-add or not, summation in SIMD lanes of another width, blocked matrix products), so its
floats may differ from the fixture's in their last digits. `assert_close` compares keys,
strings, integers and structure exactly and floats within `RTOL` and `ATOL`; `read_snapshot`
reads a JSON, CSV, TSV or ``.npz`` fixture into what it walks. `perturbed` and `write_snapshot`
make the fixtures' copies with every float moved by a factor, with which each snapshot test
shows that its comparison allows rounding and catches a change.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

RTOL = 1e-9
"""Relative tolerance of a float: one rounding moves a result by relative 1e-16, and a result
of many (a session of a few thousand RK4 steps, a cross-correlation's sums over the samples)
by that times the conditioning of its computation; 1e-9 is seven orders of magnitude above one
rounding and three below a change at relative 1e-6, which must fail."""

ATOL = 1e-12
"""Absolute tolerance of a float, in its own units: a result that is 0 on one machine comes out
as rounding (1e-17 or so) on another, which a relative tolerance alone would refuse."""

LAST_DIGIT = 1.0 + 4e-16
"""A factor that moves a float by its last digit or two (one or two units in the last place)."""

FLOAT_TEXT = re.compile(r"[-+]?(\d+\.\d*|\.\d+|\d+(?=[eE]))([eE][-+]?\d+)?")
"""Text that reads as a float: digits with a decimal point or an exponent (``"3"`` is an
integer, compared as text; ``"nan"`` and ``"inf"`` are compared as text too)."""


def assert_close(found: Any, expected: Any, where: str = "") -> None:
    """Assert that ``found`` is ``expected`` up to the rounding of floats.

    Dicts must have the same keys in the same order, lists the same length, strings, integers,
    booleans and None the same values; floats (against floats or integers, as ``==`` compares
    them), strings that read as floats (`FLOAT_TEXT`) and float arrays must agree within
    ``ATOL + RTOL * abs(expected)``; other arrays must be equal, of the same shape and dtype.

    Parameters
    ----------
    found, expected
        JSON-like values (dict, list, str, int, float, bool, None) or numpy arrays.
    where
        Where the values sit in their documents, for the failure's message.

    Raises
    ------
    AssertionError
        Naming the first place where they differ.
    """
    if isinstance(expected, np.ndarray) and expected.dtype.kind == "f":
        np.testing.assert_allclose(found, expected, rtol=RTOL, atol=ATOL, err_msg=where)
    elif isinstance(expected, np.ndarray):
        np.testing.assert_array_equal(found, expected, err_msg=where, strict=True)
    elif isinstance(expected, dict):
        assert isinstance(found, dict), f"{where}: {found!r} is not a dict"
        assert list(found) == list(expected), f"{where}: keys {list(found)} != {list(expected)}"
        for key, value in expected.items():
            assert_close(found[key], value, f"{where}[{key!r}]")
    elif isinstance(expected, list):
        assert isinstance(found, list), f"{where}: {found!r} is not a list"
        assert len(found) == len(expected), f"{where}: length {len(found)} != {len(expected)}"
        for k, (one, other) in enumerate(zip(found, expected, strict=True)):
            assert_close(one, other, f"{where}[{k}]")
    elif _is_number(expected) and _is_number(found) and _either_float(found, expected):
        assert _close(float(found), float(expected)), f"{where}: {found!r} != {expected!r}"
    elif _is_float_text(expected):
        assert _is_float_text(found), f"{where}: {found!r} != {expected!r}"
        assert _close(float(found), float(expected)), f"{where}: {found!r} != {expected!r}"
    else:
        assert type(found) is type(expected) and found == expected, (
            f"{where}: {found!r} != {expected!r}"
        )


def _close(found: float, expected: float) -> bool:
    return math.isclose(found, expected, rel_tol=0.0, abs_tol=ATOL + RTOL * abs(expected))


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _either_float(found: Any, expected: Any) -> bool:
    return isinstance(found, float) or isinstance(expected, float)


def _is_float_text(value: Any) -> bool:
    return isinstance(value, str) and FLOAT_TEXT.fullmatch(value) is not None


def perturbed(value: Any, factor: float) -> Any:
    """Return ``value`` with every float (and float text, and float array) multiplied by ``factor``.

    Integers, booleans, other strings and keys are left as they are.
    """
    if isinstance(value, np.ndarray):
        return value * factor if value.dtype.kind == "f" else value
    if isinstance(value, dict):
        return {key: perturbed(item, factor) for key, item in value.items()}
    if isinstance(value, list):
        return [perturbed(item, factor) for item in value]
    if isinstance(value, float):
        return value * factor
    if _is_float_text(value):
        return repr(float(value) * factor)
    return value


def read_snapshot(path: Path) -> Any:
    """Read a fixture: JSON as its value, CSV and TSV as rows of text cells, ``.npz`` as a dict
    of arrays."""
    if path.suffix == ".npz":
        with np.load(path) as arrays:
            return {name: arrays[name] for name in arrays.files}
    text = path.read_text()
    if path.suffix == ".json":
        return json.loads(text)
    if path.suffix in (".csv", ".tsv"):
        delimiter = "\t" if path.suffix == ".tsv" else ","
        return [list(row) for row in csv.reader(io.StringIO(text), delimiter=delimiter)]
    raise ValueError(f"{path}: not a JSON, CSV, TSV or .npz fixture")


def write_snapshot(path: Path, value: Any) -> None:
    """Write ``value`` as `read_snapshot` reads it back from ``path`` (by its suffix)."""
    if path.suffix == ".npz":
        np.savez(path, **value)
    elif path.suffix == ".json":
        path.write_text(json.dumps(value, indent=2) + "\n")
    elif path.suffix in (".csv", ".tsv"):
        with path.open("w", newline="") as file:
            delimiter = "\t" if path.suffix == ".tsv" else ","
            csv.writer(file, delimiter=delimiter, lineterminator="\n").writerows(value)
    else:
        raise ValueError(f"{path}: not a JSON, CSV, TSV or .npz fixture")


def perturb_file(path: Path, factor: float) -> None:
    """Rewrite a fixture with every float in it multiplied by ``factor`` (`perturbed`)."""
    write_snapshot(path, perturbed(read_snapshot(path), factor))
