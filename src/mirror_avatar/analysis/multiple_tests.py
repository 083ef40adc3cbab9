"""Adjusted p-values for several tests: Holm's step-down and Benjamini-Hochberg's step-up.

Both take p-values in any order, NaN for a comparison not tested (kept NaN and not counted in
the number of tests m), and return the adjusted p-values in the order given; a comparison is
rejected at level a when its adjusted p-value is below a. They equal statsmodels'
``multipletests`` (methods ``holm`` and ``fdr_bh``; tested), which collects the interpreter's
garbage on every Holm call, at a cost that grows with every object the process holds.
docs/METHODS.md, section 15.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def holm(p_values: ArrayLike) -> NDArray[np.float64]:
    """Adjust p-values for the family-wise error rate (Holm 1979).

    The i-th smallest of m p-values becomes max over j <= i of (m - j + 1) p_(j), capped at 1.

    Returns
    -------
    numpy.ndarray
        The adjusted p-values, in the order given (NaN where NaN was given).
    """
    p, order = _tested_in_order(p_values)
    adjusted = np.full(p.shape, np.nan)
    scaled = p[order] * (order.size - np.arange(order.size))
    adjusted[order] = np.minimum(np.maximum.accumulate(scaled), 1.0)
    return adjusted


def benjamini_hochberg(p_values: ArrayLike) -> NDArray[np.float64]:
    """Adjust p-values for the false discovery rate (Benjamini & Hochberg 1995): the q-values.

    The i-th smallest of m p-values becomes min over j >= i of p_(j) m / j, capped at 1; a
    comparison is a discovery at FDR q when its adjusted p-value is below q. NaN (a comparison
    not tested) stays NaN and is not counted in m.

    Returns
    -------
    numpy.ndarray
        The adjusted p-values, in the order given.
    """
    p, order = _tested_in_order(p_values)
    adjusted = np.full(p.shape, np.nan)
    scaled = p[order] * order.size / np.arange(1, order.size + 1)
    adjusted[order] = np.minimum(np.minimum.accumulate(scaled[::-1])[::-1], 1.0)
    return adjusted


def _tested_in_order(p_values: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Return the p-values as an array and the tested ones' indices (not NaN), smallest first."""
    p = np.asarray(p_values, dtype=np.float64)
    tested = np.flatnonzero(~np.isnan(p))
    return p, tested[np.argsort(p[tested], kind="stable")]
