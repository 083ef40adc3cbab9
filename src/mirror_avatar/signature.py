"""Individual motor signatures (IMS) and the distances between them (METHODS section 3).

The IMS of a trial, or of a set of trials, is the probability density of its velocity samples,
estimated by a histogram (default 200 bin centres on [-3.5, 3.5] units/s; samples outside the
range are counted in the end bins). Two signatures are compared by the earth mover's distance
(EMD): the area between their CDFs divided by the bin range, so that it lies in [0, 1].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.errors import InputError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Bins:
    """Histogram bins for velocity signatures.

    Parameters
    ----------
    n
        Number of bins.
    lo, hi
        Centres of the first and last bins (units/s).
    """

    n: int = 200
    lo: float = -3.5
    hi: float = 3.5

    @property
    def centres(self) -> Array:
        """Bin centres, shape (n,), units/s."""
        return np.linspace(self.lo, self.hi, self.n)

    @property
    def width(self) -> float:
        """Spacing of the bin centres (units/s)."""
        return (self.hi - self.lo) / (self.n - 1)


DEFAULT_BINS = Bins()


def compute_ims(velocity: ArrayLike, bins: Bins = DEFAULT_BINS) -> Array:
    """Velocity signature of one trial or of several trials pooled.

    Parameters
    ----------
    velocity
        Velocity samples (units/s), any shape; all samples are pooled.
    bins
        The histogram bins. A sample is counted in the bin whose centre is nearest; samples
        beyond the end centres go to the end bins.

    Returns
    -------
    numpy.ndarray
        Probability of each bin, shape (bins.n,), summing to 1.
    """
    v = np.asarray(velocity, dtype=np.float64).ravel()
    if v.size == 0:
        raise InputError(None, "a signature needs at least one velocity sample")
    if not np.all(np.isfinite(v)):
        raise InputError(None, "velocity has NaN or infinite values")
    index = np.clip(np.rint((v - bins.lo) / bins.width), 0, bins.n - 1).astype(np.intp)
    counts = np.bincount(index, minlength=bins.n).astype(np.float64)
    return counts / counts.sum()


def compute_emd(p: ArrayLike, q: ArrayLike, bins: Bins = DEFAULT_BINS) -> float:
    """Normalised earth mover's distance between two signatures on the same bins.

    ``sum(|cumsum(p) - cumsum(q)|) * width / (hi - lo)``: the Wasserstein-1 distance of the
    binned distributions divided by the bin range, in [0, 1].

    Parameters
    ----------
    p, q
        Probabilities, shape (bins.n,), each summing to 1.
    bins
        The bins both signatures were computed on.
    """
    return float(compute_emd_matrix(np.stack([np.asarray(p), np.asarray(q)]), bins=bins)[0, 1])


def compute_emd_matrix(
    signatures: ArrayLike, others: ArrayLike | None = None, bins: Bins = DEFAULT_BINS
) -> Array:
    """Pairwise normalised EMD between signatures, vectorised.

    Parameters
    ----------
    signatures
        Probabilities, shape (m, bins.n).
    others
        Probabilities, shape (k, bins.n); by default ``signatures`` itself.
    bins
        The bins of all signatures.

    Returns
    -------
    numpy.ndarray
        EMD matrix, shape (m, k) (or (m, m), symmetric with zero diagonal).
    """
    a = np.atleast_2d(np.asarray(signatures, dtype=np.float64))
    b = a if others is None else np.atleast_2d(np.asarray(others, dtype=np.float64))
    if a.shape[1] != bins.n or b.shape[1] != bins.n:
        raise InputError(None, f"signatures must have {bins.n} bins, got {a.shape[1]}")
    cdf_a = np.cumsum(a, axis=1)
    cdf_b = np.cumsum(b, axis=1)
    distance = np.zeros((a.shape[0], b.shape[0]))
    for start in range(0, a.shape[0], 256):
        block = cdf_a[start : start + 256, None, :] - cdf_b[None, :, :]
        distance[start : start + 256] = np.abs(block).sum(axis=2)
    return distance * bins.width / (bins.hi - bins.lo)
