"""Validation of the IMS generator on held-out human trials (paper section VI-A, METHODS 4).

For each style (trial group) a generator is fitted on two thirds of its trials and generates as
many 60 s trials as were held out. The generated motion should carry the style's signature: its
EMD to the held-out human trials comparable to the EMD between two human trials of the style and
well below the EMD between styles, its velocity strokes in the same region of the
skewness-kurtosis plane, its trials overlapping the human ones in the similarity space, and each
generated trial identified as its own style.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pandas as pd

from mirror_avatar.common.errors import InputError
from mirror_avatar.figures.signatures import plot_ims, plot_similarity_space, plot_skew_kurtosis
from mirror_avatar.files.trials import Trial, finite_difference
from mirror_avatar.motion.codebook_size import sweep_codebook
from mirror_avatar.motion.generator import PAPER_EMISSION, PAPER_SYMBOLS, IMSGenerator
from mirror_avatar.report import Section
from mirror_avatar.signatures.signature import SignatureAnalysis, analyse_signatures

TRAIN_FRACTION = 2.0 / 3.0
"""Share of each style's trials the generator is fitted on (paper: two thirds)."""

DURATION = 60.0
"""Length (s) of each generated trial, as long as a bundled human trial."""

RATE = 100.0
"""Rate (Hz) of the generators and of the signature analysis (the paper's 100 Hz)."""

SWEEP_SIZES = (32, 64, 128, 256)
QUICK_SWEEP_SIZES = (32, 128)


@dataclass
class StyleSplit:
    """One style's trials: the generator's training set, the held-out ones, the generated ones."""

    train: list[Trial]
    held_out: list[Trial]
    generated: list[Trial]


def run(trials: Sequence[Trial], quick: bool = False, seed: int = 0) -> Section:
    """Fit a generator per style on 2/3 of its trials and compare its motion with the rest.

    Parameters
    ----------
    trials
        Solo human trials; each group with at least 3 trials is a style (at least 2 styles).
    quick
        Shrink the codebook sweep to `QUICK_SWEEP_SIZES`.
    seed
        Seeds the train / held-out split, k-means and the generated trials.

    Returns
    -------
    Section
        Tables (EMD of generated vs human motion, identification, strokes, overlaps, codebook
        sweep), figures (signatures, similarity space, strokes) and metrics.
    """
    splits = split_and_generate(trials, seed)
    styles = list(splits)
    analysis, rows = analyse_splits(splits)
    emd_table = compute_style_emd(analysis, rows)
    identified = identify_styles(analysis, splits, rows)
    strokes = compare_strokes(analysis, styles)
    smoothing = measure_smoothing(splits)
    overlaps = {s: _overlap(analysis, s, _generated_group(s)) for s in styles}
    inside = {s: fraction_inside(analysis, s, _generated_group(s)) for s in styles}
    sweep = pd.concat(
        {
            s: sweep_codebook(
                lambda size: _paper_generator(size, seed),
                splits[s].train,
                splits[s].held_out,
                QUICK_SWEEP_SIZES if quick else SWEEP_SIZES,
                random_state=seed,
            )
            for s in styles
        },
        names=["style"],
    )
    checks = {
        "emd_within_1.5x_human": bool(np.all(emd_table["ratio_to_human_within"] <= 1.5)),
        "emd_below_half_between": bool(np.all(emd_table["ratio_to_between"] <= 0.5)),
        "all_identified": bool(identified["correct"].all()),
        "strokes_within_one_sd": bool(strokes["within_one_sd"].all()),
    }
    metrics: dict[str, Any] = {
        "seed": seed,
        "quick": quick,
        "duration": DURATION,
        "split": {
            s: {
                "train": [t.label for t in splits[s].train],
                "held_out": [t.label for t in splits[s].held_out],
            }
            for s in styles
        },
        "style_emd": emd_table.to_dict(orient="index"),
        "identification_accuracy": float(identified["correct"].mean()),
        "identification": identified.to_dict(orient="index"),
        "strokes": strokes.to_dict(orient="index"),
        "smoothing": smoothing.to_dict(orient="index"),
        "overlap_human_generated": overlaps,
        "generated_inside_human_region": inside,
        "codebook_sweep": sweep.reset_index().to_dict(orient="records"),
        "checks": checks,
    }
    return Section(
        key="generator",
        title="IMS generator: generated motion against held-out human motion",
        text=_describe(splits, emd_table, identified, overlaps, inside, checks),
        tables={
            "Mean EMD of generated trials to the held-out human trials, against human-vs-human "
            "EMD within the style and between styles": emd_table,
            "Identification: the style whose held-out trials are nearest in mean EMD": identified,
            "Velocity strokes, human (all trials) against generated": strokes,
            "Smoothing by quantisation: RMS velocity and acceleration, generated / human": (
                smoothing
            ),
            "Codebook sweep (fitted on the training trials, compared with the held-out ones)": (
                sweep
            ),
        },
        figures=_figures(analysis, styles),
        metrics=metrics,
    )


def split_and_generate(trials: Sequence[Trial], seed: int) -> dict[str, StyleSplit]:
    """Split each style's trials and generate as many trials as were held out.

    Each style's trials are shuffled by ``numpy.random.default_rng(seed)`` (styles in order of
    first appearance) and the first ``round(2/3 n)`` are the training set. Generators use
    ``random_state=seed`` for k-means and for sampling; generated trials are labelled
    ``"<style> generated <k>"`` in group ``"<style> (generated)"``.

    Raises
    ------
    InputError
        Fewer than 2 styles with at least 3 trials each.
    """
    rng = np.random.default_rng(seed)
    names = list(dict.fromkeys(t.group for t in trials))
    by_style = {s: [t for t in trials if t.group == s] for s in names}
    by_style = {s: members for s, members in by_style.items() if len(members) >= 3}
    if len(by_style) < 2:
        raise InputError(None, "the generator validation needs 2 groups of at least 3 trials")
    splits = {}
    for style, members in by_style.items():
        order = rng.permutation(len(members))
        n_train = round(TRAIN_FRACTION * len(members))
        train = [members[i] for i in order[:n_train]]
        held_out = [members[i] for i in order[n_train:]]
        model = _paper_generator(PAPER_SYMBOLS, seed).fit(train)
        generated = [
            replace(t, label=f"{style} generated {k + 1}", group=_generated_group(style))
            for k, t in enumerate(model.sample(DURATION, n=len(held_out), random_state=seed))
        ]
        splits[style] = StyleSplit(train, held_out, generated)
    return splits


def analyse_splits(
    splits: dict[str, StyleSplit],
) -> tuple[SignatureAnalysis, dict[str, dict[str, list[int]]]]:
    """Analyse the human then the generated trials of every style together.

    Returns
    -------
    analysis : SignatureAnalysis
        Of every style's human trials (training then held out), then every style's generated.
    rows : dict
        Style -> ``"human"``, ``"held_out"``, ``"generated"`` -> the trials' rows in ``analysis``
        (by position in the analysis, never by label: two people's trials may share a name).
    """
    rows: dict[str, dict[str, list[int]]] = {}
    ordered: list[Trial] = []
    for style, split in splits.items():
        start, middle = len(ordered), len(ordered) + len(split.train)
        ordered += split.train + split.held_out
        rows[style] = {
            "human": list(range(start, len(ordered))),
            "held_out": list(range(middle, len(ordered))),
        }
    for style, split in splits.items():
        rows[style]["generated"] = list(range(len(ordered), len(ordered) + len(split.generated)))
        ordered += split.generated
    return analyse_signatures(ordered, rate=RATE), rows


def compute_style_emd(
    analysis: SignatureAnalysis, rows: dict[str, dict[str, list[int]]]
) -> pd.DataFrame:
    """Mean EMDs per style: generated vs held-out human, human within style and between styles.

    ``human_within`` averages distinct pairs of the style's human trials (all of them),
    ``between`` every pair of human trials of two different styles. ``rows`` as
    `analyse_splits` returns them.
    """
    all_human = [i for style in rows.values() for i in style["human"]]
    table = {}
    for style, own_rows in rows.items():
        human, own, held = own_rows["human"], own_rows["generated"], own_rows["held_out"]
        others = [i for i in all_human if i not in human]
        block = analysis.emd[np.ix_(human, human)]
        within = float(block[~np.eye(len(block), dtype=bool)].mean())
        between = float(analysis.emd[np.ix_(human, others)].mean())
        generated = float(analysis.emd[np.ix_(own, held)].mean())
        table[style] = {
            "generated_vs_held_out": generated,
            "generated_vs_other_styles": float(analysis.emd[np.ix_(own, others)].mean()),
            "human_within": within,
            "between": between,
            "ratio_to_human_within": generated / within,
            "ratio_to_between": generated / between,
        }
    return pd.DataFrame.from_dict(table, orient="index")


def identify_styles(
    analysis: SignatureAnalysis,
    splits: dict[str, StyleSplit],
    rows: dict[str, dict[str, list[int]]],
) -> pd.DataFrame:
    """Assign each generated trial to the style whose held-out trials are nearest in mean EMD."""
    table = {}
    for style, split in splits.items():
        for trial, row in zip(split.generated, rows[style]["generated"], strict=True):
            distance = {s: float(analysis.emd[row, r["held_out"]].mean()) for s, r in rows.items()}
            nearest = min(distance, key=distance.__getitem__)
            table[trial.label] = {
                "style": style,
                "identified_as": nearest,
                "correct": nearest == style,
                **{f"mean_emd_to_{s}": d for s, d in distance.items()},
            }
    return pd.DataFrame.from_dict(table, orient="index")


def compare_strokes(analysis: SignatureAnalysis, styles: Sequence[str]) -> pd.DataFrame:
    """Stroke skewness and kurtosis of each style's human and generated motion.

    ``within_one_sd``: both means of the generated strokes lie within one SD (of the human
    strokes) of the human means.
    """
    statistics = analysis.stroke_statistics()
    rows = {}
    for style in styles:
        human, generated = statistics[style], statistics[_generated_group(style)]
        rows[style] = {
            **{f"human_{k}": v for k, v in human.items()},
            **{f"generated_{k}": v for k, v in generated.items()},
            "within_one_sd": all(
                abs(generated[f"{m}_mean"] - human[f"{m}_mean"]) <= human[f"{m}_sd"]
                for m in ("skewness", "kurtosis")
            ),
        }
    return pd.DataFrame.from_dict(rows, orient="index")


def fraction_inside(analysis: SignatureAnalysis, region: str, group: str) -> float | None:
    """Fraction of ``group``'s trials whose similarity-space point lies in ``region``'s ellipse.

    A complement to the overlap (intersection / union), which stays small when one region is
    estimated from a handful of nearly collinear points even if it lies inside the other. A
    region of level p holds about a fraction p of its own group's trials, the yardstick here.
    ``None`` when ``region`` has no (or a degenerate) ellipse.
    """
    ellipse = analysis.ellipses[region]
    if ellipse is None or not np.all(ellipse.semi_axes > 0):
        return None
    points = analysis.points_by_group()[group]
    scaled = (points - ellipse.centre) @ ellipse.axes / ellipse.semi_axes
    return float(np.mean(np.sum(scaled**2, axis=1) <= 1.0))


def measure_smoothing(splits: dict[str, StyleSplit]) -> pd.DataFrame:
    """RMS velocity (units/s) and acceleration (units/s²) of human and generated motion.

    Quantised neighbouring frames disagree and their overlap-add averages them (METHODS 4,
    step 5): an acceleration ratio generated / human below 1 measures that smoothing, one above
    1 the extra acceleration of the chain's jumps between dissimilar frames. On the bundled
    data (seeds 0-7) the velocity ratio was 0.93-1.19 and the acceleration ratio 0.73-1.25.
    Human = all the style's trials at `RATE`.
    """
    rows = {}
    for style, split in splits.items():
        human = [t.resampled(RATE) for t in split.train + split.held_out]
        values = {}
        for name, trials in (("human", human), ("generated", split.generated)):
            velocity = [t.velocity() for t in trials]
            acceleration = [finite_difference(v, 1.0 / RATE) for v in velocity]
            values[f"{name}_velocity_rms"] = _rms(velocity)
            values[f"{name}_acceleration_rms"] = _rms(acceleration)
        values["velocity_ratio"] = values["generated_velocity_rms"] / values["human_velocity_rms"]
        values["acceleration_ratio"] = (
            values["generated_acceleration_rms"] / values["human_acceleration_rms"]
        )
        rows[style] = values
    return pd.DataFrame.from_dict(rows, orient="index")


def _rms(signals: list[np.ndarray]) -> float:
    return float(np.sqrt(np.mean(np.concatenate(signals) ** 2)))


def _overlap(analysis: SignatureAnalysis, a: str, b: str) -> float | None:
    names = analysis.group_names
    value = float(analysis.overlaps[names.index(a), names.index(b)])
    return value if np.isfinite(value) else None


def _paper_generator(n_symbols: int, seed: int) -> IMSGenerator:
    """Make an unfitted generator as the paper's: ``n_symbols`` code vectors, at `RATE`."""
    return IMSGenerator(n_symbols, rate=RATE, random_state=seed, emission=PAPER_EMISSION)


def _generated_group(style: str) -> str:
    return f"{style} (generated)"


def _figures(analysis: SignatureAnalysis, styles: Sequence[str]) -> dict[str, Any]:
    groups = [g for s in styles for g in (s, _generated_group(s))]
    group_ims = dict(zip(analysis.group_names, analysis.group_ims, strict=True))
    strokes = analysis.strokes_by_group()
    return {
        "Velocity signature of each style, human and generated": plot_ims(
            {g: group_ims[g] for g in groups}, analysis.bins
        ),
        f"Similarity space with each group's {analysis.level:.0%} region": plot_similarity_space(
            {g: p for g, p in analysis.points_by_group().items() if g in groups},
            {g: analysis.ellipses[g] for g in groups},
        ),
        "Skewness and kurtosis of velocity strokes, human and generated": plot_skew_kurtosis(
            {g: strokes[g] for g in groups}, {g: analysis.stroke_ellipses[g] for g in groups}
        ),
    }


def _describe(
    splits: dict[str, StyleSplit],
    emd_table: pd.DataFrame,
    identified: pd.DataFrame,
    overlaps: dict[str, float | None],
    inside: dict[str, float | None],
    checks: dict[str, bool],
) -> list[str]:
    text = [
        "For each style a generator (256 symbols) was fitted on "
        + ", ".join(f"{len(sp.train)} {s} trials" for s, sp in splits.items())
        + f" and generated as many {DURATION:g} s trials as were held out.",
    ]
    for style, row in emd_table.iterrows():
        overlap, share = overlaps[str(style)], inside[str(style)]
        text.append(
            f"{style}: mean EMD generated vs held-out human {row['generated_vs_held_out']:.4f}, "
            f"human vs human within the style {row['human_within']:.4f} "
            f"(ratio {row['ratio_to_human_within']:.2f}), between styles {row['between']:.4f} "
            f"(ratio {row['ratio_to_between']:.2f}); overlap of the human and generated regions "
            + ("n/a" if overlap is None else f"{overlap:.2f}")
            + ", generated trials inside the human region "
            + ("n/a" if share is None else f"{share:.0%}")
            + "."
        )
    text.append(
        f"{int(identified['correct'].sum())} of {len(identified)} generated trials are nearest "
        "to their own style's held-out trials. Checks: "
        + ", ".join(f"{name} {'yes' if ok else 'NO'}" for name, ok in checks.items())
        + "."
    )
    return text
