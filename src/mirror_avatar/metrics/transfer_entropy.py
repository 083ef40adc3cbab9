"""Transfer entropy between two players' velocities: how much one's past tells of the other's next.

Schreiber (2000, Phys Rev Lett 85:461): with the target ``y``, the source ``x`` and the
target's history of ``k`` values ``y_t^(k)``,
``TE(x -> y) = sum p(y_{t+1}, y_t^(k), x_t) log2 p(y_{t+1} | y_t^(k), x_t) / p(y_{t+1} | y_t^(k))``,
in bits. The plug-in estimator on discrete series is pyinform's (`pyinform.transfer_entropy`, the
Python face of the C library inform, Moore et al. 2018). **Choice** of library: pyinform is small,
has no runtime beyond its C core (IDTxl and JIDT need Java or a large stack), estimates exactly the
quantity above on discrete states, and pools several series of one process (the sub-sampled
phases below) into one estimate; its numbers are checked against a slow hand-written plug-in
estimator in the tests.

**Choice** of states: each velocity series is cut into ``bins`` equiprobable bins (its own
quantiles), and the series is read every ``step`` seconds (all ``step * rate`` phases of the
sub-sampling pooled), so that one step of the estimator is a time over which a partner can react
rather than one sample of a smooth signal. Defaults: 4 bins, history 2, step 0.1 s.
"""

from __future__ import annotations

import numpy as np
import pyinform
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.common.errors import InputError

BINS = 4
"""Equiprobable bins of each velocity (**choice**)."""

HISTORY = 2
"""Length of the target's history, in steps (**choice**)."""

STEP = 0.1
"""Time between the estimator's steps (s, **choice**)."""


def discretise(x: ArrayLike, bins: int = BINS) -> NDArray[np.int32]:
    """States 0 .. bins - 1 of a series cut at its own quantiles (equiprobable bins), shape (n,)."""
    a = np.asarray(x, dtype=float)
    edges = np.quantile(a, np.linspace(0.0, 1.0, bins + 1)[1:-1])
    return np.searchsorted(edges, a, side="right").astype(np.int32)


def phases(states: NDArray[np.int32], stride: int) -> NDArray[np.int32]:
    """Cut ``states`` into its ``stride`` sub-sampled copies ``states[p::stride]``, shape (p, m)."""
    length = states.size // stride
    return np.array([states[p::stride][:length] for p in range(stride)], dtype=np.int32)


def transfer_entropy(
    source: ArrayLike, target: ArrayLike, rate: float, history: int = HISTORY,
    bins: int = BINS, step: float = STEP,
) -> float:  # fmt: skip
    """Transfer entropy (bits) from ``source`` to ``target`` (module docstring).

    Parameters
    ----------
    source, target
        Velocities (units/s) of two players, shape (n,), uniform at ``rate`` (Hz).
    rate
        Sampling rate (Hz).
    history
        Target history ``k`` (steps).
    bins
        Equiprobable bins per series.
    step
        Time between the estimator's steps (s); at least one sample.
    """
    x, y = np.asarray(source, dtype=float), np.asarray(target, dtype=float)
    stride = max(1, round(step * rate))
    if x.ndim != 1 or x.shape != y.shape or x.size // stride <= history + 1:
        raise InputError(
            "transfer entropy", "series shorter than the history (--te-history, --te-step)"
        )
    if bins < 2 or history < 1:
        raise InputError(
            "transfer entropy", f"need --te-bins >= 2 and --te-history >= 1, got {bins}, {history}"
        )
    return states_transfer_entropy(discretise(x, bins), discretise(y, bins), stride, history)


def states_transfer_entropy(
    source: NDArray[np.int32], target: NDArray[np.int32], stride: int, history: int = HISTORY
) -> float:
    """Transfer entropy (bits) between two discretised series (`discretise`), read every ``stride``.

    `transfer_entropy` once its series are cut into states: a series' states computed once serve
    every partner (a circular shift of a series has its states shifted alike).
    """
    sx, sy = phases(source, stride), phases(target, stride)
    return float(pyinform.transfer_entropy(sx, sy, k=history))
