"""A first-order Markov chain over symbols: counted, estimated and walked.

What the IMS generator (`mirror_avatar.motion.generator`, METHODS section 4, step 4) learns over its
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


def group_members(
    symbols: NDArray[np.int64], n_symbols: int, fallback: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Each symbol's frames, as offsets into one index array (compressed rows).

    Parameters
    ----------
    symbols
        The symbol of each frame, shape (n_frames,).
    n_symbols
        Number of symbols.
    fallback
        Frame index that stands for symbol s when no frame has it is ``fallback + s`` (the
        symbol's code vector, placed after the frames).

    Returns
    -------
    starts : numpy.ndarray
        Symbol s's frames are ``members[starts[s]:starts[s + 1]]``, shape (n_symbols + 1,).
    members : numpy.ndarray
        Frame indices grouped by symbol, in frame order within a symbol.
    """
    present = np.bincount(symbols, minlength=n_symbols) > 0
    missing = np.flatnonzero(~present)
    owners = np.concatenate([symbols, missing])
    frames = np.concatenate([np.arange(symbols.size), fallback + missing]).astype(np.int64)
    order = np.argsort(owners, kind="stable")
    counts = np.bincount(owners, minlength=n_symbols)
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return starts, frames[order]


@njit(cache=True, nogil=True)
def emit_exemplars(
    sequence: NDArray[np.int64],
    uniforms: Array,
    starts: NDArray[np.int64],
    members: NDArray[np.int64],
    following: NDArray[np.int64],
    frame_symbols: NDArray[np.int64],
) -> NDArray[np.int64]:
    """Choose, for each symbol of a sequence, one of the training frames it stands for.

    The frame that followed the previous choice in its trial is taken when it has the symbol
    (the chain is retracing a training trial); otherwise one of the symbol's frames, drawn
    evenly with the uniform of that step.

    Parameters
    ----------
    sequence
        Symbols, shape (length,).
    uniforms
        Uniform draws in [0, 1), shape (length,).
    starts, members
        The symbols' frames (`group_members`).
    following
        Index of the frame that followed each frame in its trial, -1 at a trial's end (or for
        a code vector), shape (n_frames,).
    frame_symbols
        Symbol of each frame, shape (n_frames,).

    Returns
    -------
    numpy.ndarray
        Frame indices, shape (length,).
    """
    chosen = np.empty(sequence.size, dtype=np.int64)
    previous = -1
    for k in range(sequence.size):
        symbol = sequence[k]
        successor = following[previous] if 0 <= previous < following.size else -1
        if successor >= 0 and frame_symbols[successor] == symbol:
            previous = successor
        else:
            count = starts[symbol + 1] - starts[symbol]
            previous = members[starts[symbol] + min(int(uniforms[k] * count), count - 1)]
        chosen[k] = previous
    return chosen
