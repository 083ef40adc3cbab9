"""Generated motion against each person's held-out trials: the whole likeness battery, per person.

Protocol (issue 47; docs/METHODS.md sections 3 and 4b):

- **People**: the two bundled styles (`mirror_avatar.datasets.load_zhai2017`, nine trials of
  60 s each, each style taken as one person) and the synthetic people
  (`mirror_avatar.datasets.synthetic.SYNTHETIC_PEOPLE`, ten trials of 60 s each, seed 0).
  ``--people development`` runs the bundled styles and `DEVELOPMENT_PEOPLE`, the only people any
  choice of a generator's design or settings looked at; ``--people test`` runs `TEST_PEOPLE`,
  held out of every choice; ``--people all`` both; ``--people fresh`` runs `FRESH_PEOPLE`, held
  out for the next round of choices.
- **Split**: a person's first `FITTED` trials fit the generator (timed: wall clock of ``fit``);
  the others are held out. The generator makes one trial per held-out trial, as long as it
  (seeds 1, 2, ...; ``--sets N`` makes N sets of generated trials, set s with seeds
  ``1 + SET_SEEDS * s``, ... , and prints each person's mean AUC over the sets: one set moves a
  person's AUC by up to 0.1).
- **Battery** (`compare_motion`, seed 0, `PERMUTATIONS` permutations): generated against held-out
  trials, the person's own variability from all their trials; the classifier's AUC and p, and the
  ratio of each distance (velocity IMS EMD, amplitude, spectrum) to the person's own.
- **Data-copying** (`copying_test`): the fitted trials as training, the held-out trials as fresh
  motion, the generated trials; C_T and the median nearest-training distance ratio.
- **Shared**: kind ``shared`` is the stroke generator written shareable
  (`mirror_avatar.motion.sharing.shareable`, groups of `DEFAULT_GROUP_SIZE`); for both stroke
  kinds, the rebuild ratio is the median `rebuild_errors` of the fitted trials' strokes over the
  held-out trials' (0: the training trials rebuilt exactly; about 1: no better than trials never
  seen).
- **The person's own**: kind ``person`` takes the fitted trials as the generated ones, the
  battery's values for a generator that played the training trials back.
- **Identification**: each generated trial is put with the person whose held-out trials are
  nearest on average (mean velocity-IMS EMD, every person of the run a candidate); the ceiling is
  the same rule for each held-out trial against the other held-out trials (its own left out).

Run: ``python benchmarks/likeness_people.py --people development --kinds ims strokes`` (prints a
Markdown table, and writes ``--json`` rows when given).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.datasets.synthetic import (
    DEVELOPMENT_PEOPLE,
    FRESH_PEOPLE,
    SYNTHETIC_PEOPLE,
    TEST_PEOPLE,
)
from mirror_avatar.files.trials import Trial
from mirror_avatar.motion.models import MODEL_KINDS, MotionModel
from mirror_avatar.motion.sharing import DEFAULT_GROUP_SIZE, rebuild_errors, shareable
from mirror_avatar.motion.strokes import StrokeGenerator
from mirror_avatar.signatures.copying import copying_test
from mirror_avatar.signatures.likeness import (
    compare_motion,
    ims_distances,
    trial_velocity,
    velocity_spectrum,
)

FITTED = 5
"""Trials each generator is fitted on (issue 47: 5 trials)."""

SYNTHETIC_TRIALS = 10
"""Trials of each synthetic person (5 fitted, 5 held out)."""

PERMUTATIONS = 199
"""Permutations of each test of the battery."""

RATE = 100.0

SET_SEEDS = 1000
"""Seed offset between sets of generated trials (``--sets``)."""


def people(which: str) -> dict[str, list[Trial]]:
    """Each person's trials, bundled styles first (``development``, ``test`` or ``all``)."""
    chosen: dict[str, list[Trial]] = {}
    if which in ("development", "all"):
        bundled = load_zhai2017()
        for style in ("slow", "fast"):
            chosen[f"bundled {style}"] = [t for t in bundled if t.group == style]
    names = {"development": DEVELOPMENT_PEOPLE, "test": TEST_PEOPLE, "fresh": FRESH_PEOPLE}.get(
        which, DEVELOPMENT_PEOPLE + TEST_PEOPLE
    )
    for name in names:
        chosen[name] = SYNTHETIC_PEOPLE[name].trials(SYNTHETIC_TRIALS, 60.0, seed=0)
    return chosen


KINDS = (*MODEL_KINDS, "shared", "person")
"""What plays the generated trials: a generator kind, its shareable stroke model, the person."""


def fit(kind: str, trials: Sequence[Trial], settings: dict[str, Any]) -> MotionModel:
    """Return a generator of ``kind`` (``shared``: strokes, then made shareable) fitted, seed 0."""
    if kind == "shared":
        return shareable(fit("strokes", trials, settings), DEFAULT_GROUP_SIZE)
    return MODEL_KINDS[kind](random_state=0, **settings).fit(trials)


def rebuild_ratio(model: MotionModel, fitted: Sequence[Trial], held: Sequence[Trial]) -> float:
    """Median rebuild error of the fitted trials' strokes over the held-out trials' (NaN: IMS)."""
    if not isinstance(model, StrokeGenerator):
        return float("nan")
    training = np.median(rebuild_errors(model, list(fitted)))
    return float(training / np.median(rebuild_errors(model, list(held))))


def measure(
    name: str, trials: Sequence[Trial], kind: str, settings: dict[str, Any], first_seed: int = 1
) -> tuple[dict[str, Any], list]:
    """Measure the battery, data-copying test and fit time of one person and one generator kind.

    Kind ``person`` takes the fitted trials themselves as the generated ones (each cut to its
    held-out trial's length): what a perfect copy of the training trials would score. The
    generated trials have seeds ``first_seed``, ``first_seed + 1``, ...
    """
    fitted, held = list(trials[:FITTED]), list(trials[FITTED:])
    start = time.perf_counter()
    rebuilt = float("nan")
    if kind == "person":
        generated = [
            trial_velocity(f, RATE)[: round(t.duration * RATE) + 1]
            for f, t in zip(fitted, held, strict=False)
        ]
    else:
        model = fit(kind, fitted, settings)
        generated = [
            model.sample_velocity(round(t.duration * RATE) + 1, seed)
            for seed, t in enumerate(held, start=first_seed)
        ]
    fit_seconds = time.perf_counter() - start
    if kind != "person":
        rebuilt = rebuild_ratio(model, fitted, held)
    reference = [trial_velocity(t, RATE) for t in held]
    own = [trial_velocity(t, RATE) for t in trials]
    result = compare_motion(reference, generated, own=own, rate=RATE, n_permutations=PERMUTATIONS)
    copying = copying_test([trial_velocity(t, RATE) for t in fitted], reference, generated, RATE)
    ratios = {d.measure: d.ratio for d in result.distances}
    classifier = result.classifier
    row = {
        "person": name,
        "kind": kind,
        "auc": classifier.auc if classifier else float("nan"),
        "auc_p": classifier.test.p_value if classifier else float("nan"),
        "emd_ratio": ratios["velocity IMS EMD"],
        "amplitude_ratio": ratios["amplitude"],
        "spectrum_ratio": ratios["spectrum"],
        "copying_ct": copying.c_t,
        "copying_distance_ratio": copying.distance_ratio,
        "rebuild_ratio": rebuilt,
        "fit_seconds": fit_seconds,
        "verdict": result.verdict(),
    }
    return row, [reference, generated]


def identification(signals: dict[str, list]) -> tuple[dict[str, float], float]:
    """Share of each person's generated trials put with them, and the held-out ceiling."""
    names = list(signals)
    held = [v for name in names for v in signals[name][0]]
    owner = np.array([k for k, name in enumerate(names) for _ in signals[name][0]])
    generated = [v for name in names for v in signals[name][1]]
    creator = np.array([k for k, name in enumerate(names) for _ in signals[name][1]])
    emd = ims_distances([*held, *generated])
    n = len(held)
    to_held = emd[:, :n]
    rates = {}
    for k, name in enumerate(names):
        rows = n + np.flatnonzero(creator == k)
        means = np.stack([to_held[rows][:, owner == q].mean(axis=1) for q in range(len(names))])
        rates[name] = float(np.mean(np.argmin(means, axis=0) == k))
    hits = []
    for i in range(n):
        others = np.arange(n) != i
        means = [to_held[i, others & (owner == q)].mean() for q in range(len(names))]
        hits.append(int(np.argmin(means)) == owner[i])
    return rates, float(np.mean(hits))


def mean_spectrum(velocities: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Return the frequencies (Hz) and the mean of the signals' normalised velocity spectra."""
    spectra = [velocity_spectrum(v, RATE) for v in velocities]
    return spectra[0][0], np.mean([power for _, power in spectra], axis=0)


def draw_spectra(spectra: dict[str, dict[str, list]], path: Path) -> None:
    """Draw each person's held-out and generated velocity spectra, one panel a person."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(next(iter(spectra.values())))
    columns = min(3, len(names))
    rows = -(-len(names) // columns)
    figure, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.2 * rows), squeeze=False)
    for axis, name in zip(axes.flat, names, strict=False):
        frequencies, held = mean_spectrum(next(iter(spectra.values()))[name][0])
        axis.semilogy(frequencies, held, color="black", lw=2, label="held-out trials")
        for kind, signals in spectra.items():
            if kind != "person":
                axis.semilogy(*mean_spectrum(signals[name][1]), lw=1.2, label=f"{kind} generator")
        axis.set_title(name)
        axis.set_xlabel("frequency (Hz)")
        axis.set_ylabel("share of velocity power")
        axis.set_ylim(1e-6, 1)
    for axis in list(axes.flat)[len(names) :]:
        axis.axis("off")
    axes.flat[0].legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=110)


def table(rows: Sequence[dict[str, Any]]) -> str:
    """Return the rows as a Markdown table."""
    head = (
        "| person | generator | AUC (p) | IMS EMD ratio | amplitude ratio | spectrum ratio | "
        "identified | data-copying C_T (distance ratio) | rebuild ratio | fit (s) |\n"
        "|---|---|---|---|---|---|---|---|---|---|"
    )
    lines = [
        f"| {r['person']} | {r['kind']} | {r['auc']:.2f} ({r['auc_p']:.3f}) | "
        f"{r['emd_ratio']:.2f} | {r['amplitude_ratio']:.2f} | {r['spectrum_ratio']:.2f} | "
        f"{r['identified']:.0%} | {r['copying_ct']:.1f} ({r['copying_distance_ratio']:.2f}) | "
        f"{r['rebuild_ratio']:.2f} | {r['fit_seconds']:.1f} |"
        for r in rows
    ]
    return "\n".join([head, *lines])


def other_sets(
    rows: Sequence[dict[str, Any]],
    everyone: dict[str, list[Trial]],
    settings: dict[str, Any],
    sets: int,
) -> None:
    """Add each row's AUC over ``sets`` sets of generated trials (``set_aucs``, the row's first)."""
    for row in rows:
        row["set_aucs"] = [row["auc"]] + [
            measure(
                row["person"], everyone[row["person"]], row["kind"], settings, 1 + SET_SEEDS * s
            )[0]["auc"]
            for s in range(1, sets)
        ]
        print(
            f"{row['person']} {row['kind']}: mean AUC {np.mean(row['set_aucs']):.3f} over "
            f"{sets} sets ({', '.join(f'{a:.2f}' for a in row['set_aucs'])})",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--people", choices=("development", "test", "fresh", "all"), default="development"
    )
    parser.add_argument("--kinds", nargs="+", choices=KINDS, default=["strokes"])
    parser.add_argument(
        "--set", nargs="*", default=[], help="generator settings KEY=VALUE (numbers)"
    )
    parser.add_argument(
        "--sets", type=int, default=1, help="sets of generated trials (seeds 1000 apart)"
    )
    parser.add_argument("--json", type=Path, help="also write the rows to this file")
    parser.add_argument(
        "--figure", type=Path, help="also draw each person's velocity spectra (PNG) to this file"
    )
    args = parser.parse_args()
    settings = {k: int(v) if v.isdigit() else float(v) for k, v in (i.split("=") for i in args.set)}
    everyone = people(args.people)
    rows, spectra = [], {}
    for kind in args.kinds:
        signals, kind_rows = {}, []
        for name, trials in everyone.items():
            row, signals[name] = measure(
                name, trials, kind, settings if kind in ("strokes", "shared") else {}
            )
            kind_rows.append(row)
            print(f"{name} {kind}: {row['verdict']}", flush=True)
        spectra[kind] = signals
        rates, ceiling = identification(signals)
        for row in kind_rows:
            row["identified"] = rates[row["person"]]
            row["identification_ceiling"] = ceiling
        if args.sets > 1 and kind != "person":
            other_sets(
                kind_rows, everyone, settings if kind in ("strokes", "shared") else {}, args.sets
            )
        rows += kind_rows
    print(table(rows))
    print(f"identification ceiling (held-out trials among held-out trials): {ceiling:.0%}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    if args.figure:
        draw_spectra(spectra, args.figure)


if __name__ == "__main__":
    main()
