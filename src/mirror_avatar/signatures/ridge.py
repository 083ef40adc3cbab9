"""The classifier test's linear classifier and its AUC, in numpy.

`ridge_scores` is scikit-learn's ``make_pipeline(StandardScaler(), RidgeClassifier())`` fitted
on two classes and its ``decision_function`` (features standardised on the training rows, a
constant feature left unscaled; labels as -1 and +1; ridge with penalty `ALPHA` on the centred
data and an intercept); `roc_auc` is the Mann-Whitney form of ``roc_auc_score`` (average ranks for
ties). Both are tested against scikit-learn. The classifier test fits one classifier per fold
and relabelling (hundreds of fits of a few hundred windows); scikit-learn's input validation
took most of that time.
"""

from __future__ import annotations

import numpy as np
import scipy.stats
from numpy.typing import NDArray

Array = NDArray[np.float64]

ALPHA = 1.0
"""Ridge penalty on the standardised features (scikit-learn's default)."""


def ridge_scores(x_train: Array, y_train: NDArray[np.bool_], x_test: Array) -> Array:
    """Fit a ridge classifier on standardised features and score the test rows.

    Parameters
    ----------
    x_train, x_test
        Features, shape (n_train, n_features) and (n_test, n_features).
    y_train
        Classes of the training rows, shape (n_train,), both present.

    Returns
    -------
    numpy.ndarray
        Shape (n_test,): higher for the True class.
    """
    mean = x_train.mean(axis=0)
    scale = x_train.std(axis=0)
    scale[scale < 10 * np.finfo(np.float64).eps] = 1.0
    train = (x_train - mean) / scale
    targets = np.where(y_train, 1.0, -1.0)
    centre = train.mean(axis=0)
    centred = train - centre
    gram = centred.T @ centred + ALPHA * np.eye(centred.shape[1])
    coefficients = np.linalg.solve(gram, centred.T @ (targets - targets.mean()))
    intercept = targets.mean() - centre @ coefficients
    return ((x_test - mean) / scale) @ coefficients + intercept


def roc_auc(y: NDArray[np.bool_], scores: Array) -> float:
    """Area under the ROC curve of ``scores`` for telling True from False rows, shape (n,).

    The probability that a True row scores above a False one, ties counted half (Mann-Whitney
    U over the product of the two counts).
    """
    ranks = scipy.stats.rankdata(scores)
    positives = int(y.sum())
    negatives = y.size - positives
    u = ranks[y].sum() - positives * (positives + 1) / 2.0
    return float(u / (positives * negatives))
