"""How faithful a generator is from a few trials: the codebook size chosen from the data, or fixed.

A person gives n solo trials (n = 3, 5, 9 per style by default); the generator is fitted on them
with its codebook size chosen by cross-validation
(`mirror_avatar.motion.codebook_size.choose_n_symbols`) and, for comparison, with the paper's fixed
256 symbols. Each generates one 60 s trial per held-out trial of the person, and the score is the
**ratio** of the mean EMD between the generated and the held-out trials' IMS to the mean EMD between
the person's own trials and the
held-out ones (1: the generator is as close to the person's unseen motion as the person's other
trials are). Held-out trials are the style's trials not given: for n below the style's count,
``repeats`` random draws of n trials; for n equal to it, each trial in turn is held out and the
generator fitted on the others (n - 1 given). **Identification**: the share of generated trials
whose IMS is on average nearer the held-out trials of their own style than any other style's.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.progress import counted
from mirror_avatar.files.trials import Trial
from mirror_avatar.motion.generator import PAPER_SYMBOLS, IMSGenerator
from mirror_avatar.report import Section
from mirror_avatar.signatures.signature import compute_emd, compute_ims

TRIALS_GIVEN = (3, 5, 9)
QUICK_TRIALS_GIVEN = (3,)
REPEATS, QUICK_REPEATS = 4, 1
DURATION = 60.0
"""Length (s) of each generated trial, as long as a bundled human trial."""

RATE = 100.0
METHODS: dict[str, int | str] = {"chosen (auto)": "auto", f"fixed {PAPER_SYMBOLS}": PAPER_SYMBOLS}


def run(trials: Sequence[Trial], quick: bool = False, seed: int = 0) -> Section:
    """Measure the EMD ratio and identification for every style with enough trials.

    Parameters
    ----------
    trials
        Solo human trials grouped by style (``group``); each style is evaluated for the n it
        has trials for (at least two styles with 3 trials each, or the section says it was
        skipped).
    quick
        n in `QUICK_TRIALS_GIVEN`, `QUICK_REPEATS` draws.
    seed
        Seeds the draws, the generators and their trials.
    """
    counts = QUICK_TRIALS_GIVEN if quick else TRIALS_GIVEN
    title = "IMS generator from a few trials: codebook size chosen from the data"
    text = [
        "A person gives n solo trials; their generator is fitted on them with the codebook size "
        "chosen by cross-validation on those trials, and with the paper's fixed 256 symbols. "
        "Each generates one 60 s trial per held-out trial of the style. Ratio: the mean EMD "
        "between generated and held-out IMS over the mean EMD between the person's own trials "
        "and the held-out ones (1: as close to the person's unseen motion as their other trials "
        "are). With n below the style's count, random draws of n trials; with all of them, each "
        "is held out in turn and the others fitted. Identified: the share of generated trials "
        "nearer (mean EMD) their own style's held-out trials than any other style's."
    ]
    try:
        rows = evaluate_complexity(trials, counts, QUICK_REPEATS if quick else REPEATS, seed)
    except InputError as error:
        return Section("generator_complexity", title, [*text, f"Skipped: {error.problem}."])
    table = summarise(rows)
    return Section(
        key="generator_complexity",
        title=title,
        text=text,
        tables={"EMD ratio to held-out trials and identification, per trials given": table},
        metrics={"table": table.reset_index().to_dict(orient="records")},
    )


def evaluate_complexity(
    trials: Sequence[Trial], counts: Sequence[int], repeats: int, seed: int
) -> list[dict[str, Any]]:
    """One row per style, n, draw and method: ratio, identification and codebook size."""
    styles = _styles(trials, min(counts))
    ims = {style: [_ims(t) for t in group] for style, group in styles.items()}
    rng = np.random.default_rng(seed)
    draws = [
        (style, group, n, draw, held)
        for style, group in styles.items()
        for n in counts
        if n <= len(group)
        for draw, held in enumerate(_held_out_sets(len(group), n, repeats, rng))
    ]
    rows = []
    for style, group, n, draw, held in counted(draws, len(draws), "generator complexity", "draw"):
        given = [t for k, t in enumerate(group) if k not in held]
        for method, symbols in METHODS.items():
            model = IMSGenerator(symbols, rate=RATE, random_state=seed + draw)
            model.fit(given)
            generated = [_ims(g) for g in model.sample(DURATION, len(held), seed + draw)]
            target = [ims[style][k] for k in held]
            own = [ims[style][k] for k in range(len(group)) if k not in held]
            rows.append(
                {
                    "style": style,
                    "trials given": _given(n, len(group)),
                    "method": method,
                    "n_symbols": model.n_symbols_,
                    "ratio": _mean_emd(generated, target) / _mean_emd(own, target),
                    "identified": _identified(generated, style, ims, held),
                }
            )
    return rows


def summarise(rows: list[dict[str, Any]]) -> pd.DataFrame:
    """Mean ratio and identification, and the codebook sizes, per style, n and method."""
    frame = pd.DataFrame(rows)
    grouped = frame.groupby(["style", "trials given", "method"], sort=False)
    return pd.DataFrame(
        {
            "EMD ratio (mean)": grouped["ratio"].mean().round(3),
            "EMD ratio (worst)": grouped["ratio"].max().round(3),
            "identified": grouped["identified"].mean().round(3),
            "symbols": grouped["n_symbols"].apply(lambda s: "/".join(map(str, sorted(set(s))))),
            "draws": grouped.size(),
        }
    )


def _styles(trials: Sequence[Trial], needed: int) -> dict[str, list[Trial]]:
    groups: dict[str, list[Trial]] = {}
    for trial in trials:
        groups.setdefault(trial.group, []).append(trial.resampled(RATE))
    styles = {name: group for name, group in groups.items() if len(group) >= needed}
    if len(styles) < 2:
        raise InputError("trials", f"it needs two styles with at least {needed} trials each")
    return styles


def _given(n: int, count: int) -> str:
    """Label the trials a person gave: n, or n - 1 when each of all n is held out in turn."""
    return str(n) if n < count else f"{n} ({n - 1} fitted, 1 held out in turn)"


def _held_out_sets(count: int, n: int, repeats: int, rng: np.random.Generator) -> list[list[int]]:
    """Trials held out of ``count``: random complements of n, or each in turn if n is all."""
    if n >= count:
        return [[k] for k in range(count)]
    return [sorted(rng.permutation(count)[n:].tolist()) for _ in range(repeats)]


def _ims(trial: Trial) -> np.ndarray:
    return compute_ims(trial.velocity())


def _mean_emd(a: Sequence[np.ndarray], b: Sequence[np.ndarray]) -> float:
    return float(np.mean([compute_emd(x, y) for x in a for y in b]))


def _identified(
    generated: Sequence[np.ndarray], style: str, ims: dict[str, list[np.ndarray]], held: list[int]
) -> float:
    """Share of generated IMS nearer (mean EMD) their style's held-out trials than any other."""
    references = {s: group for s, group in ims.items() if s != style}
    references[style] = [ims[style][k] for k in held]
    hits = [
        min(references, key=lambda s: _mean_emd([g], references[s])) == style for g in generated
    ]
    return float(np.mean(hits))
