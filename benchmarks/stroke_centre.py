"""Where an oscillation's centre goes: the person's held-out trials against the stroke generator's.

The centre of a back-and-forth motion, measured stroke by stroke: each stroke's **midpoint**, half
way between the reversals at its two ends (`mirror_avatar.motion.strokes.reversals`, the
generator's ``min_reversal``). How far the centre moves over L strokes is the square root of the
midpoints' semivariogram (Cressie, "Statistics for spatial data", 1993, chapter 2),
``sqrt(mean((m[k + L] - m[k])^2) / 2)`` (units): it grows without end for a centre that
random-walks (as sqrt(L)), and levels off at the midpoints' SD for a centre held in place. Beside
it, the share of velocity power below 0.5 Hz
(`mirror_avatar.signatures.likeness.velocity_spectrum`), the band the battery found separating
the oscillating people.

Protocol: `likeness_people.py`'s people and split (5 trials fitted, the others held out), the
stroke generator of the checked-out package, ``--sets`` sets of one generated trial per held-out
trial (seeds as `likeness_people.py --sets` gives them).

Run: ``python benchmarks/stroke_centre.py --people development --sets 3`` (prints a Markdown
table).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np
from likeness_people import FITTED, RATE, SET_SEEDS, people

from mirror_avatar.files.trials import compute_velocity
from mirror_avatar.motion.strokes import StrokeGenerator, reversals
from mirror_avatar.signatures.likeness import velocity_spectrum

LAGS = (1, 8)
"""Strokes over which the centre's movement is reported."""

LOW_BAND = 0.5
"""Upper edge (Hz) of the velocity band reported."""


def midpoint_changes(positions: np.ndarray, lags: Sequence[int], min_reversal: float) -> list:
    """Return how far (units) the strokes' midpoints move over each lag (strokes), NaN if fewer.

    The first and last strokes (cut by the trial's ends) are left out.
    """
    ends = positions[reversals(positions, min_reversal)][1:-1]
    middles = (ends[:-1] + ends[1:]) / 2
    return [
        float(np.sqrt(np.mean((middles[lag:] - middles[:-lag]) ** 2) / 2))
        if middles.size > lag
        else float("nan")
        for lag in lags
    ]


def centre(positions: np.ndarray, min_reversal: float) -> list:
    """Return the midpoint changes over `LAGS` and the velocity power share below `LOW_BAND`."""
    frequencies, power = velocity_spectrum(compute_velocity(positions, RATE), RATE)
    return [*midpoint_changes(positions, LAGS, min_reversal), power[frequencies < LOW_BAND].sum()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--people", choices=("development", "test", "fresh", "all"), default="development"
    )
    parser.add_argument("--sets", type=int, default=3, help="sets of generated trials")
    args = parser.parse_args()
    lags = " / ".join(f"{lag} stroke{'s' * (lag > 1)}" for lag in LAGS)
    print(
        f"| person | centre moves over {lags}: held out | generated | "
        f"velocity power below {LOW_BAND} Hz: held out | generated |\n|---|---|---|---|---|"
    )
    for name, trials in people(args.people).items():
        model = StrokeGenerator(random_state=0).fit(trials[:FITTED])
        held = [model.signal(t) for t in trials[FITTED:]]
        person = np.nanmean([centre(x, model.min_reversal) for x in held], axis=0)
        generated = np.nanmean(
            [
                centre(model.sample_positions(x.size, seed + SET_SEEDS * s), model.min_reversal)
                for s in range(args.sets)
                for seed, x in enumerate(held, start=1)
            ],
            axis=0,
        )
        moves = [" / ".join(f"{v:.3f}" for v in values[:-1]) for values in (person, generated)]
        print(
            f"| {name} | {moves[0]} | {moves[1]} | {person[-1]:.2e} | {generated[-1]:.2e} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
