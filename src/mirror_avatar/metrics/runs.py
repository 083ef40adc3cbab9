"""Runs of a boolean series: where a condition holds without a break, and for how long."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def find_runs(mask: ArrayLike) -> NDArray[np.int64]:
    """Start and stop indices of the runs of True in ``mask``.

    Parameters
    ----------
    mask
        Boolean series, shape (n,).

    Returns
    -------
    ndarray
        Shape (k, 2), integers: each run is ``mask[start:stop]``, in order of time.
    """
    m = np.asarray(mask, dtype=bool).ravel()
    edges = np.diff(np.concatenate(([0], m.astype(np.int8), [0])))
    return np.column_stack((np.flatnonzero(edges == 1), np.flatnonzero(edges == -1))).astype(
        np.int64
    )


def keep_long_runs(mask: ArrayLike, min_samples: int) -> NDArray[np.bool_]:
    """``mask`` with every run of True shorter than ``min_samples`` samples set to False.

    A mask of shape (..., n) is taken as series along its last axis, each on its own.
    """
    m = np.asarray(mask, dtype=bool)
    if m.ndim > 1:
        return np.array([keep_long_runs(row, min_samples) for row in m]).reshape(m.shape)
    m = m.ravel()
    out = np.zeros_like(m)
    for start, stop in find_runs(m):
        if stop - start >= min_samples:
            out[start:stop] = True
    return out
