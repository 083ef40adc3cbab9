"""Motor signatures of solo trials: can the groups' movement styles be told apart (METHODS 3).

Computes each trial's IMS, the EMD between every pair of trials, the similarity space and each
group's characteristic region, and the skewness and kurtosis of every velocity stroke, and checks
them against the magnitudes the literature reports.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from mirror_avatar.figures.signatures import (
    HUMAN_KURTOSIS,
    HUMAN_SKEWNESS,
    plot_ims,
    plot_similarity_space,
    plot_skew_kurtosis,
)
from mirror_avatar.files.trials import Trial
from mirror_avatar.report import Section
from mirror_avatar.signatures.signature import (
    SignatureAnalysis,
    analyse_signatures,
    confidence_ellipse,
    ellipse_overlap,
)


def run(trials: Sequence[Trial], quick: bool = False, seed: int = 0) -> Section:
    """Signature analysis of ``trials`` grouped by ``trial.group``.

    Parameters
    ----------
    trials
        Solo trials, at least 3, in at least one group.
    quick
        Accepted for the experiments' common interface; this analysis takes well under a second
        on the bundled data, so it is the same either way.
    seed
        Seeds the random halves of each group used by the overlap check.

    Returns
    -------
    Section
        Figures (signatures, similarity space, strokes), tables (mean EMD within and between
        groups, stroke statistics against human ranges, overlaps) and metrics.
    """
    del quick
    analysis = analyse_signatures(trials)
    emd_table = compute_group_emd(analysis)
    within, between = compute_within_between(analysis)
    halves = compute_half_overlaps(analysis, seed)
    overlaps = pd.DataFrame(
        analysis.overlaps, index=analysis.group_names, columns=analysis.group_names
    )
    distinct = _off_diagonal(analysis.overlaps)
    distinct = distinct[np.isfinite(distinct)]
    max_between = float(distinct.max()) if distinct.size else float("nan")
    min_self = float(halves["overlap"].min()) if len(halves) else float("nan")
    metrics: dict[str, Any] = {
        "n_trials": len(analysis.labels),
        "groups": analysis.group_names,
        "seed": seed,
        "level": analysis.level,
        "mean_within_emd": within,
        "mean_between_emd": between,
        "between_within_ratio": between / within if within > 0 else float("nan"),
        "group_emd": emd_table.to_dict(),
        "overlaps": overlaps.to_dict(),
        "max_between_overlap": max_between,
        "min_half_overlap": min_self,
        "half_overlaps": halves.reset_index().to_dict(orient="records"),
        "styles_distinct": _verdict(max_between, min_self),
        "stroke_statistics": analysis.stroke_statistics(),
    }
    return Section(
        key="signature",
        title="Individual motor signatures",
        text=_describe(analysis, within, between, max_between, min_self),
        tables={
            "Mean EMD between the trials of two groups (diagonal: distinct pairs within a group)": (
                emd_table
            ),
            "Overlap of the groups' regions in the similarity space (intersection / union)": (
                overlaps
            ),
            "Each group's region against itself re-estimated on a random half of its trials": (
                halves
            ),
            "Velocity strokes against human ranges (skewness "
            f"{HUMAN_SKEWNESS}, kurtosis {HUMAN_KURTOSIS})": stroke_table(analysis),
        },
        figures={
            "Velocity signature of each group (thin lines: single trials)": plot_ims(
                dict(zip(analysis.group_names, analysis.group_ims, strict=True)),
                analysis.bins,
                trial_ims={g: analysis.ims[analysis.members(g)] for g in analysis.group_names},
            ),
            f"Similarity space with each group's {analysis.level:.0%} region": (
                plot_similarity_space(analysis.points_by_group(), analysis.ellipses)
            ),
            "Skewness and kurtosis of velocity strokes (dashed: human range)": plot_skew_kurtosis(
                analysis.strokes_by_group(), analysis.stroke_ellipses
            ),
        },
        metrics=metrics,
    )


def compute_group_emd(analysis: SignatureAnalysis) -> pd.DataFrame:
    """Mean EMD between the trials of each pair of groups, a (g, g) table.

    The diagonal averages distinct pairs of trials of the same group (self-pairs excluded).
    """
    names = analysis.group_names
    table = np.full((len(names), len(names)), np.nan)
    for i, a in enumerate(names):
        for j, b in enumerate(names):
            block = analysis.emd[np.ix_(analysis.members(a), analysis.members(b))]
            values = _off_diagonal(block) if i == j else block.ravel()
            table[i, j] = values.mean() if values.size else np.nan
    return pd.DataFrame(table, index=names, columns=names)


def compute_within_between(analysis: SignatureAnalysis) -> tuple[float, float]:
    """Mean EMD over all pairs of distinct trials of the same group, and of different groups."""
    groups = np.asarray(analysis.groups)
    upper = np.triu(np.ones_like(analysis.emd, dtype=bool), k=1)
    same = groups[:, None] == groups[None, :]
    within = analysis.emd[upper & same]
    between = analysis.emd[upper & ~same]
    return _mean(within), _mean(between)


def compute_half_overlaps(analysis: SignatureAnalysis, seed: int) -> pd.DataFrame:
    """Overlap of each group's region with the region of each half of its trials.

    Each group's trials are shuffled with ``numpy.random.default_rng(seed)`` (groups in order)
    and split into two halves (the first half gets the larger share); each half's ellipse is
    estimated from the same similarity-space coordinates. Halves with fewer than 3 trials are
    skipped. Two styles are told apart when they overlap less than every group overlaps with
    its halves.
    """
    rng = np.random.default_rng(seed)
    rows = []
    for name in analysis.group_names:
        ellipse = analysis.ellipses[name]
        members = rng.permutation(analysis.members(name))
        for half, indices in enumerate(np.array_split(members, 2), start=1):
            if ellipse is None or indices.size < 3:
                continue
            region = confidence_ellipse(analysis.coordinates[indices], analysis.level)
            trials = ", ".join(analysis.labels[i] for i in sorted(indices))
            rows.append(
                {
                    "group": name,
                    "half": half,
                    "trials": trials,
                    "overlap": ellipse_overlap(ellipse, region),
                }
            )
    return pd.DataFrame(rows, columns=["group", "half", "trials", "overlap"]).set_index(
        ["group", "half"]
    )


def stroke_table(analysis: SignatureAnalysis) -> pd.DataFrame:
    """Each group's stroke statistics and the share of its strokes in the human ranges (%)."""
    table = pd.DataFrame(analysis.stroke_statistics()).T.rename(columns=STROKE_COLUMNS)
    table["strokes"] = table["strokes"].astype(int)
    moments = analysis.strokes_by_group()
    table["in human range (%)"] = [
        100 * _fraction_in_range(moments[g]) if moments[g].size else np.nan for g in table.index
    ]
    return table


STROKE_COLUMNS = {
    "n_strokes": "strokes",
    "skewness_mean": "skewness mean",
    "skewness_sd": "skewness SD",
    "kurtosis_mean": "kurtosis mean",
    "kurtosis_sd": "kurtosis SD",
}
"""The stroke statistics' names (`SignatureAnalysis.stroke_statistics`) in words."""


def _fraction_in_range(moments: np.ndarray) -> float:
    skew_ok = (moments[:, 0] > HUMAN_SKEWNESS[0]) & (moments[:, 0] < HUMAN_SKEWNESS[1])
    kurt_ok = (moments[:, 1] > HUMAN_KURTOSIS[0]) & (moments[:, 1] < HUMAN_KURTOSIS[1])
    return float(np.mean(skew_ok & kurt_ok))


def _describe(
    analysis: SignatureAnalysis, within: float, between: float, max_between: float, min_self: float
) -> list[str]:
    text = [
        f"{len(analysis.labels)} trials in {len(analysis.group_names)} groups "
        f"({', '.join(analysis.group_names)}), resampled to {analysis.rate:g} Hz. The IMS is the "
        f"histogram of velocity on {analysis.bins.n} bins over [{analysis.bins.lo:g}, "
        f"{analysis.bins.hi:g}] units/s; EMD is normalised by the bin range (0 to 1). Literature: "
        "same person 0.002-0.025, different people 0.01-0.1.",
        f"Mean EMD within groups {within:.4f}, between groups {between:.4f} "
        f"(ratio {between / within if within > 0 else float('nan'):.1f}).",
    ]
    distinct = _verdict(max_between, min_self)
    if distinct is not None:
        verdict = "apart" if distinct else "NOT apart"
        text.append(
            f"Regions ({analysis.level:.0%} confidence ellipses): the largest overlap between two "
            f"groups is {max_between:.2f}, the smallest overlap of a group with its own region "
            f"re-estimated on half its trials is {min_self:.2f}: the styles are told {verdict}."
        )
    return text


def _verdict(max_between: float, min_self: float) -> bool | None:
    """Whether the styles are told apart; ``None`` when either overlap could not be computed."""
    if np.isfinite(max_between) and np.isfinite(min_self):
        return bool(max_between < min_self)
    return None


def _off_diagonal(matrix: np.ndarray) -> np.ndarray:
    rows, columns = np.indices(matrix.shape)
    return matrix[rows != columns]


def _mean(values: np.ndarray) -> float:
    return float(values.mean()) if values.size else float("nan")
