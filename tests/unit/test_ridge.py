"""The classifier test's ridge classifier and AUC against scikit-learn's."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.linear_model import RidgeClassifier
from sklearn.metrics import roc_auc_score
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from mirror_avatar.signatures.ridge import ridge_scores, roc_auc


def windows(seed: int, rows: int, features: int) -> tuple[np.ndarray, np.ndarray]:
    """Features of two overlapping classes, on scales from 1e-3 to 1e3, one feature constant."""
    rng = np.random.default_rng(seed)
    y = rng.random(rows) < 0.4
    x = rng.normal(size=(rows, features)) + 0.5 * y[:, None]
    x *= np.logspace(-3, 3, features)
    x[:, 1] = 2.5
    return x, y


@pytest.mark.parametrize(("seed", "rows", "features"), [(0, 40, 6), (1, 300, 14), (2, 9, 14)])
def test_scores_equal_scikit_learns_pipeline(seed: int, rows: int, features: int) -> None:
    x, y = windows(seed, rows, features)
    train, test = slice(0, 2 * rows // 3), slice(2 * rows // 3, None)
    model = make_pipeline(StandardScaler(), RidgeClassifier()).fit(x[train], y[train])
    expected = model.decision_function(x[test])
    found = ridge_scores(x[train], y[train], x[test])
    np.testing.assert_allclose(found, expected, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_auc_equals_scikit_learns_with_ties(seed: int) -> None:
    rng = np.random.default_rng(seed)
    y = rng.random(80) < 0.3
    scores = rng.integers(0, 12, 80).astype(float)  # many ties
    assert roc_auc(y, scores) == pytest.approx(roc_auc_score(y, scores), abs=1e-14)


def test_auc_of_perfect_and_reversed_scores() -> None:
    y = np.array([False, False, True, True])
    assert roc_auc(y, np.array([0.0, 1.0, 2.0, 3.0])) == 1.0
    assert roc_auc(y, np.array([3.0, 2.0, 1.0, 0.0])) == 0.0
    assert roc_auc(y, np.ones(4)) == 0.5
