"""The time `study report`'s mixed models take per measure, with and without random slopes.

Protocol: a synthetic study of ``--participants`` participants in two counterbalanced
conditions, ``--trials`` trials each, one measure: a participant's level (SD 1), a condition
effect of 0.3 whose spread over participants is ``--slope-sd`` (0: no slope variance, so the
slopes are tried and left out), trial noise SD 0.5. Each seed's measure is fitted by
`mirror_avatar.analysis.statistics.fit_contrasts` (the random effects chosen, Satterthwaite's
df); the wall time of each fit is printed with the structure chosen and the df.

Run: ``python benchmarks/study_models.py --seeds 5 --slope-sd 0`` and ``--slope-sd 0.5``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

from mirror_avatar.analysis.statistics import fit_contrasts

CONDITIONS = ("a", "b")


def study(seed: int, participants: int, trials: int, slope_sd: float) -> pd.DataFrame:
    """Rows of one synthetic study (one per participant, condition and trial)."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(participants):
        level, effect = rng.normal(0.0, 1.0), 0.3 + rng.normal(0.0, slope_sd)
        order = CONDITIONS if i % 2 == 0 else CONDITIONS[::-1]
        for position, condition in enumerate(order, start=1):
            for trial in range(1, trials + 1):
                value = level + effect * (condition == "b") + rng.normal(0.0, 0.5)
                rows.append({"participant": f"p{i}", "condition": condition, "block": position,
                             "position": position, "trial": trial, "y": value})  # fmt: skip
    return pd.DataFrame(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--participants", type=int, default=12)
    parser.add_argument("--trials", type=int, default=4)
    parser.add_argument("--slope-sd", type=float, default=0.0)
    args = parser.parse_args()
    print("| seed | random effects | df | s |\n|---|---|---|---|")
    for seed in range(args.seeds):
        rows = study(seed, args.participants, args.trials, args.slope_sd)
        start = time.perf_counter()
        model = fit_contrasts(rows, "y", CONDITIONS, "a")
        took = time.perf_counter() - start
        assert model is not None
        print(f"| {seed} | {model.random_effects} | {model.contrasts[0].df:.1f} | {took:.2f} |")


if __name__ == "__main__":
    main()
