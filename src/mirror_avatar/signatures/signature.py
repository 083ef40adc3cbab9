"""Individual motor signatures (IMS) and the distances between them (METHODS section 3).

The IMS of a trial, or of a set of trials, is the probability density of its velocity samples,
estimated by a histogram (default 200 bin centres on [-3.5, 3.5] units/s; samples outside the
range are counted in the end bins). Two signatures are compared by the earth mover's distance
(EMD): the area between their CDFs divided by the bin range, so that it lies in [0, 1].

Also the analyses built on them: the similarity space, characteristic regions and their overlaps,
and velocity strokes, composed by `analyse_signatures`; one module because they are one analysis.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.stats
from numba import njit
from numpy.typing import ArrayLike, NDArray
from shapely.geometry import Polygon

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.progress import counted
from mirror_avatar.files.atomic import json_safe
from mirror_avatar.files.trials import Trial

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
        The histogram bins (see `count_velocities`).

    Returns
    -------
    numpy.ndarray
        Probability of each bin, shape (bins.n,), summing to 1.
    """
    counts = count_velocities(velocity, bins)
    return counts / counts.sum()


def count_velocities(velocity: ArrayLike, bins: Bins = DEFAULT_BINS) -> Array:
    """Histogram counts of velocity samples, the signature before normalising.

    Counts of several batches add up to the counts of the batches pooled.

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
        Samples per bin, shape (bins.n,), as floats.
    """
    v = np.asarray(velocity, dtype=np.float64).ravel()
    if v.size == 0:
        raise InputError(None, "a signature needs at least one velocity sample")
    counts = np.zeros(bins.n)
    if not _count_into(counts, v, bins.lo, bins.width):
        raise InputError(None, "velocity has NaN or infinite values")
    return counts


@njit(cache=True, nogil=True)
def _count_into(counts: Array, velocity: Array, lo: float, width: float) -> bool:
    """Add each sample to the bin of the nearest centre (`count_velocities`), in one pass.

    The nearest centre is ``rint((v - lo) / width)`` (ties to even), clipped to the end bins.
    Returns False, with ``counts`` partly filled, at the first sample that is not finite.
    """
    last = counts.size - 1
    for v in velocity:
        if not np.isfinite(v):
            return False
        counts[min(max(int(np.rint((v - lo) / width)), 0), last)] += 1.0
    return True


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


def classical_mds(distances: ArrayLike, n_components: int = 2) -> Array:
    """Classical (Torgerson) multidimensional scaling of a distance matrix (METHODS section 3).

    Double-centres ``-D**2 / 2`` and returns the top eigenvectors scaled by the square roots of
    their eigenvalues; negative eigenvalues (a non-Euclidean ``D``) are clipped to zero. Each axis
    is oriented so that its largest-magnitude coordinate is positive, which makes the result
    deterministic.

    Parameters
    ----------
    distances
        Symmetric distance matrix, shape (m, m), zero diagonal.
    n_components
        Number of dimensions to keep.

    Returns
    -------
    numpy.ndarray
        Coordinates, shape (m, n_components); Euclidean distances between rows approximate
        ``distances``. Columns beyond ``m`` are zero.
    """
    d = np.asarray(distances, dtype=np.float64)
    if d.ndim != 2 or d.shape[0] != d.shape[1]:
        raise InputError(None, f"distances must be a square matrix, got shape {d.shape}")
    if not np.all(np.isfinite(d)):
        raise InputError(None, "distances have NaN or infinite values")
    m = d.shape[0]
    centring = np.eye(m) - 1.0 / m
    gram = -0.5 * centring @ (d**2) @ centring
    values, vectors = np.linalg.eigh((gram + gram.T) / 2)
    order = np.argsort(values)[::-1][:n_components]
    values = np.clip(values[order], 0.0, None)
    vectors = vectors[:, order]
    largest = vectors[np.argmax(np.abs(vectors), axis=0), np.arange(vectors.shape[1])]
    vectors = vectors * np.where(largest < 0, -1.0, 1.0)
    coordinates = np.zeros((m, n_components))
    coordinates[:, : vectors.shape[1]] = vectors * np.sqrt(values)
    return coordinates


@dataclass(frozen=True, eq=False)
class Ellipse:
    """A Gaussian confidence ellipse in a plane.

    Parameters
    ----------
    centre
        Centre, shape (2,).
    axes
        Unit axis directions as columns, shape (2, 2); the first column is the major axis.
    semi_axes
        Semi-axis lengths along those directions, shape (2,).
    level
        Probability mass of the Gaussian the ellipse encloses.
    """

    centre: Array
    axes: Array
    semi_axes: Array
    level: float

    @property
    def area(self) -> float:
        """Exact area ``pi * a * b``."""
        return float(np.pi * self.semi_axes[0] * self.semi_axes[1])

    def boundary(self, n_points: int = 512) -> Array:
        """Points on the ellipse, shape (n_points, 2), counter-clockwise, not closed."""
        angle = np.linspace(0.0, 2 * np.pi, n_points, endpoint=False)
        unit = np.stack([np.cos(angle), np.sin(angle)])
        return (self.centre[:, None] + self.axes @ (self.semi_axes[:, None] * unit)).T

    def polygon(self, quad_segs: int = 128) -> Polygon:
        """Return the ellipse as a shapely polygon with ``4 * quad_segs`` vertices.

        The inscribed polygon's area is ``pi a b (1 - O((pi / (2 quad_segs))**2))``: 0.0025 %
        low at the default.
        """
        return Polygon(self.boundary(4 * quad_segs))

    def to_json_dict(self) -> dict[str, Any]:
        """Return the ellipse as plain lists and numbers."""
        return {
            "centre": self.centre.tolist(),
            "axes": self.axes.tolist(),
            "semi_axes": self.semi_axes.tolist(),
            "level": self.level,
            "area": self.area,
        }


def confidence_ellipse(points: ArrayLike, level: float = 0.7) -> Ellipse:
    """Gaussian confidence ellipse of planar points (a player's characteristic region).

    Centre = mean; axes = eigenvectors of the sample covariance (``ddof=1``); semi-axes
    ``sqrt(chi2_2.ppf(level) * eigenvalue)``. The level is a **choice** (METHODS: 0.7).

    Parameters
    ----------
    points
        Points, shape (k, 2), k >= 3.
    level
        Probability in (0, 1).
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise InputError(None, f"points must have shape (k, 2), got {p.shape}")
    if p.shape[0] < 3:
        raise InputError(None, f"an ellipse needs at least 3 points, got {p.shape[0]}")
    if not 0.0 < level < 1.0:
        raise InputError("level", f"must be in (0, 1), got {level}")
    values, vectors = np.linalg.eigh(np.cov(p, rowvar=False))
    values, vectors = np.clip(values[::-1], 0.0, None), vectors[:, ::-1]
    scale = float(scipy.stats.chi2.ppf(level, df=2))
    return Ellipse(p.mean(axis=0), vectors, np.sqrt(scale * values), float(level))


def ellipse_overlap(a: Ellipse, b: Ellipse, quad_segs: int = 128) -> float:
    """Area of intersection over area of union of two ellipses, in [0, 1].

    Computed on shapely polygons with ``4 * quad_segs`` vertices. Two degenerate (zero-area)
    ellipses have overlap 0.
    """
    pa, pb = a.polygon(quad_segs), b.polygon(quad_segs)
    union = pa.union(pb).area
    return 0.0 if union == 0.0 else float(pa.intersection(pb).area / union)


def velocity_strokes(velocity: ArrayLike, min_samples: int = 20) -> list[Array]:
    """Split a velocity signal into strokes between consecutive zero crossings.

    A crossing is where the sign of the velocity changes. Exact zeros (tracking drop-outs give
    runs of them) take the sign of the last non-zero sample before them (samples before the first
    non-zero one take its sign), so a pause inside a stroke does not split it, and a pause
    between two strokes of opposite directions ends the first stroke.

    Parameters
    ----------
    velocity
        Velocity, shape (n,), units/s.
    min_samples
        Strokes with fewer samples are dropped (METHODS: 20 at 100 Hz).

    Returns
    -------
    list of numpy.ndarray
        The velocity of each complete stroke; the incomplete first and last segments are left out.
    """
    v = np.asarray(velocity, dtype=np.float64).ravel()
    sign = np.sign(v)
    nonzero = np.flatnonzero(sign)
    if nonzero.size == 0:
        return []
    last_nonzero = np.maximum.accumulate(np.where(sign != 0, np.arange(v.size), nonzero[0]))
    sign = sign[last_nonzero]
    crossings = np.flatnonzero(sign[1:] != sign[:-1]) + 1
    strokes = [v[start:stop] for start, stop in zip(crossings[:-1], crossings[1:], strict=True)]
    return [stroke for stroke in strokes if stroke.size >= min_samples]


def compute_stroke_moments(stroke: ArrayLike) -> tuple[float, float]:
    """Skewness and kurtosis of one stroke's speed profile (METHODS section 3).

    Time is rescaled to [0, 1] (sample i at ``i / (n - 1)``), ``|v|`` is normalised to unit area
    and treated as a density ``f``; the moments are integrated with the trapezoid rule on that
    grid. Kurtosis is Pearson's (3 for a Gaussian), not the excess.

    Parameters
    ----------
    stroke
        Velocity of one stroke, shape (n,), n >= 3, not all zero.

    Returns
    -------
    tuple of float
        ``(skewness, kurtosis)``.
    """
    speed = np.abs(np.asarray(stroke, dtype=np.float64))
    if speed.size < 3 or not np.any(speed > 0):
        raise InputError(None, "a stroke needs at least 3 samples and some motion")
    t = np.linspace(0.0, 1.0, speed.size)
    f = speed / np.trapezoid(speed, t)
    mu = np.trapezoid(t * f, t)
    variance = np.trapezoid((t - mu) ** 2 * f, t)
    skewness = np.trapezoid((t - mu) ** 3 * f, t) / variance**1.5
    kurtosis = np.trapezoid((t - mu) ** 4 * f, t) / variance**2
    return float(skewness), float(kurtosis)


def stroke_moments(velocity: ArrayLike, min_samples: int = 20) -> Array:
    """Skewness and kurtosis of every complete stroke of a velocity signal.

    Parameters
    ----------
    velocity
        Velocity, shape (n,), units/s.
    min_samples
        Minimum stroke length in samples (see `velocity_strokes`).

    Returns
    -------
    numpy.ndarray
        Shape (k, 2): columns skewness and kurtosis (Pearson), one row per stroke.
    """
    strokes = velocity_strokes(velocity, min_samples)
    return np.array([compute_stroke_moments(s) for s in strokes]).reshape(-1, 2)


@dataclass
class SignatureAnalysis:
    """Everything the signature analysis of a set of trials finds (see `analyse_signatures`).

    Parameters
    ----------
    labels, groups
        Label and group of each trial, length m; labels are distinct (`distinct_labels`).
    group_names
        The distinct groups in order of first appearance, length g.
    bins
        Bins of the signatures.
    ims
        Signature of each trial, shape (m, bins.n).
    group_ims
        Signature of each group (its trials' velocities pooled), shape (g, bins.n).
    emd
        Pairwise EMD between trials, shape (m, m).
    coordinates
        Similarity-space coordinates (classical MDS of ``emd``), shape (m, 2).
    ellipses
        Group -> confidence ellipse of its trials' coordinates (``None`` with fewer than 3 trials).
    overlaps
        Pairwise overlap of the groups' ellipses, shape (g, g) (NaN where an ellipse is missing).
    strokes
        Skewness and kurtosis of each trial's strokes, one (k_i, 2) array per trial.
    stroke_ellipses
        Group -> confidence ellipse of its strokes' (skewness, kurtosis) points (``None`` with
        fewer than 3 strokes).
    level, rate
        Confidence level of the ellipses and the rate (Hz) trials were resampled to.
    """

    labels: list[str]
    groups: list[str]
    group_names: list[str]
    bins: Bins
    ims: Array
    group_ims: Array
    emd: Array
    coordinates: Array
    ellipses: dict[str, Ellipse | None]
    overlaps: Array
    strokes: list[Array]
    stroke_ellipses: dict[str, Ellipse | None]
    level: float
    rate: float

    def members(self, group: str) -> NDArray[np.intp]:
        """Return the indices of the trials of ``group``."""
        return np.flatnonzero(np.asarray(self.groups) == group)

    def points_by_group(self) -> dict[str, Array]:
        """Group -> similarity-space coordinates of its trials, shape (k, 2)."""
        return {g: self.coordinates[self.members(g)] for g in self.group_names}

    def strokes_by_group(self) -> dict[str, Array]:
        """Group -> (skewness, kurtosis) of all its trials' strokes, shape (k, 2)."""
        return {
            g: np.concatenate([self.strokes[i] for i in self.members(g)]).reshape(-1, 2)
            for g in self.group_names
        }

    def stroke_statistics(self) -> dict[str, dict[str, float]]:
        """Group -> number of strokes and mean and SD (``ddof=1``) of skewness and kurtosis."""
        return {g: _moment_summary(m) for g, m in self.strokes_by_group().items()}

    def trial_stroke_statistics(self) -> dict[str, dict[str, float]]:
        """Trial label -> number of strokes and mean and SD of skewness and kurtosis."""
        return {
            label: _moment_summary(m) for label, m in zip(self.labels, self.strokes, strict=True)
        }

    def to_json_dict(self) -> dict[str, Any]:
        """Return the analysis as plain lists, numbers and ``None`` (for NaN), for JSON."""
        return {
            "labels": self.labels,
            "groups": self.groups,
            "group_names": self.group_names,
            "bins": {"n": self.bins.n, "lo": self.bins.lo, "hi": self.bins.hi},
            "level": self.level,
            "rate": self.rate,
            "emd": self.emd.tolist(),
            "coordinates": self.coordinates.tolist(),
            "ellipses": {g: _ellipse_json(e) for g, e in self.ellipses.items()},
            "overlaps": json_safe(self.overlaps),
            "stroke_statistics": json_safe(self.stroke_statistics()),
            "trial_stroke_statistics": json_safe(self.trial_stroke_statistics()),
            "stroke_ellipses": {g: _ellipse_json(e) for g, e in self.stroke_ellipses.items()},
        }


def analyse_signatures(
    trials: Sequence[Trial],
    bins: Bins = DEFAULT_BINS,
    level: float = 0.7,
    rate: float = 100.0,
    min_samples: int = 20,
) -> SignatureAnalysis:
    """Signatures, EMDs, similarity space, regions and strokes of trials grouped by ``group``.

    Parameters
    ----------
    trials
        At least 2 trials (an EMD matrix needs two); each is resampled to ``rate`` before its
        velocity is computed. A group with fewer than 3 trials, or with fewer than 3 strokes,
        gets no ellipse (None), and its overlaps are NaN.
    bins
        Bins of the signatures.
    level
        Confidence level of the ellipses (**choice**, METHODS: 0.7).
    rate
        Resampling rate (Hz); the paper upsamples to 100 Hz.
    min_samples
        Minimum stroke length in samples.
    """
    if len(trials) < 2:
        raise InputError(None, f"the signature analysis needs at least 2 trials, got {len(trials)}")
    velocities = [
        trial.resampled(rate).velocity()
        for trial in counted(trials, len(trials), "signatures", "trial")
    ]
    groups = [trial.group for trial in trials]
    names = list(dict.fromkeys(groups))
    ims = np.stack([compute_ims(v, bins) for v in velocities])
    pooled = {
        name: [v for v, g in zip(velocities, groups, strict=True) if g == name] for name in names
    }
    group_ims = np.stack([compute_ims(np.concatenate(pooled[name]), bins) for name in names])
    emd = compute_emd_matrix(ims, bins=bins)
    coordinates = classical_mds(emd, 2)
    strokes = [stroke_moments(v, min_samples) for v in velocities]
    analysis = SignatureAnalysis(
        labels=distinct_labels(trials),
        groups=groups,
        group_names=names,
        bins=bins,
        ims=ims,
        group_ims=group_ims,
        emd=emd,
        coordinates=coordinates,
        ellipses={},
        overlaps=np.empty((0, 0)),
        strokes=strokes,
        stroke_ellipses={},
        level=level,
        rate=rate,
    )
    analysis.ellipses = {
        g: _optional_ellipse(p, level) for g, p in analysis.points_by_group().items()
    }
    analysis.stroke_ellipses = {
        g: _optional_ellipse(p, level) for g, p in analysis.strokes_by_group().items()
    }
    analysis.overlaps = compute_overlap_matrix([analysis.ellipses[g] for g in names])
    return analysis


def distinct_labels(trials: Sequence[Trial]) -> list[str]:
    """Return the trials' labels, those that repeat qualified until each names one trial.

    Trials are told apart by their source (`mirror_avatar.cli.trial_sets` labels them by path), but
    trials from elsewhere may share a label: a repeated label gets its group in front
    (``person1/trial_00``), and one still repeated its place among its twins (``trial_00 (2)``).
    """
    labels = [trial.label or "trial" for trial in trials]
    counts = Counter(labels)
    labels = [
        f"{trial.group}/{label}" if counts[label] > 1 and trial.group else label
        for label, trial in zip(labels, trials, strict=True)
    ]
    counts, seen = Counter(labels), Counter[str]()
    distinct = []
    for label in labels:
        seen[label] += 1
        distinct.append(label if counts[label] == 1 else f"{label} ({seen[label]})")
    return distinct


def compute_overlap_matrix(ellipses: Sequence[Ellipse | None]) -> Array:
    """Pairwise `ellipse_overlap`, shape (g, g); NaN where either ellipse is ``None``."""
    n = len(ellipses)
    overlaps = np.full((n, n), np.nan)
    for i, a in enumerate(ellipses):
        for j, b in enumerate(ellipses[i:], start=i):
            if a is not None and b is not None:
                overlaps[i, j] = overlaps[j, i] = ellipse_overlap(a, b)
    return overlaps


def _optional_ellipse(points: Array, level: float) -> Ellipse | None:
    return confidence_ellipse(points, level) if points.shape[0] >= 3 else None


def _ellipse_json(ellipse: Ellipse | None) -> dict[str, Any] | None:
    return None if ellipse is None else ellipse.to_json_dict()


def _moment_summary(moments: Array) -> dict[str, float]:
    k = moments.shape[0]
    mean = moments.mean(axis=0) if k else np.full(2, np.nan)
    sd = moments.std(axis=0, ddof=1) if k > 1 else np.full(2, np.nan)
    return {
        "n_strokes": k,
        "skewness_mean": float(mean[0]),
        "skewness_sd": float(sd[0]),
        "kurtosis_mean": float(mean[1]),
        "kurtosis_sd": float(sd[1]),
    }
