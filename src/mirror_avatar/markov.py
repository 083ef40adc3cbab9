"""A first-order Markov chain over symbols: counted, estimated and walked.

What the IMS generator (`mirror_avatar.generator`, METHODS section 4, step 4) learns over its
codebook's symbols: transitions counted over the training sequences (maximum likelihood), a
pseudo-count in every cell so every row is a distribution, and a compiled inverse-CDF walk.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit
from numpy.typing import NDArray

Array = NDArray[np.float64]


@njit(cache=True, nogil=True)
def sample_chain(cumulative: Array, start_cumulative: Array, uniforms: Array) -> NDArray[np.int64]:
    """Walk a Markov chain by inverse-CDF sampling.

    Parameters
    ----------
    cumulative
        Row-wise cumulative transition probabilities, shape (n, n), last column 1.
    start_cumulative
        Cumulative initial distribution, shape (n,).
    uniforms
        Uniform draws in [0, 1), one per symbol of the sequence, shape (length,).

    Returns
    -------
    numpy.ndarray
        The symbol sequence, shape (length,).
    """
    n = start_cumulative.size
    sequence = np.empty(uniforms.size, dtype=np.int64)
    state = min(np.searchsorted(start_cumulative, uniforms[0], side="right"), n - 1)
    sequence[0] = state
    for k in range(1, uniforms.size):
        state = min(np.searchsorted(cumulative[state], uniforms[k], side="right"), n - 1)
        sequence[k] = state
    return sequence


def count_transitions(sequences: Sequence[NDArray[np.int64]], n_symbols: int) -> Array:
    """Transition counts ``C[i, j]`` = times symbol j followed symbol i, shape (n, n)."""
    counts = np.zeros((n_symbols, n_symbols))
    for sequence in sequences:
        np.add.at(counts, (sequence[:-1], sequence[1:]), 1.0)
    return counts


def estimate_transitions(counts: Array, pseudo_count: float) -> Array:
    """Row-normalised transition matrix from counts plus ``pseudo_count`` per cell."""
    smoothed = counts + pseudo_count
    totals = smoothed.sum(axis=1, keepdims=True)
    uniform = np.full_like(smoothed, 1.0 / smoothed.shape[1])
    return np.divide(smoothed, totals, out=uniform, where=totals > 0)
