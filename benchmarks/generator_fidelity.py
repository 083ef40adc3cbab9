"""Generator fidelity on held-out bundled people: velocity-IMS EMD ratio and identification.

Protocol (issue 38, point 1; docs/METHODS.md section 4, "Fidelity"):

- **People**: the two bundled styles (`mirror_avatar.datasets.load_zhai2017`), each taken as one
  person: nine solo trials of 60 s, resampled to 100 Hz.
- **Development and report halves**: every trial is cut into its first and its second 30 s.
  Settings are chosen on the first halves (``--part development``); the numbers reported are
  measured on the second halves (``--part report``), which no choice has looked at.
  ``--part whole`` runs the same folds on the whole 60 s trials, as the issue measured (both
  halves together, so not held out from the development).
- **Folds**: for each person, `FOLDS` partitions of their nine halves drawn at random (seeded),
  each 5 halves to fit a generator on and 4 held out, as the issue's 5 fitted and 5 held-out
  trials; the fitted generator makes one trial per held-out half, as long as it.
- **Ratio**: median EMD between the velocity IMS of a generated trial and of a held-out half
  (every pair of the fold), divided by the median EMD between two held-out halves of the fold;
  per person, the median of the folds' ratios, and the pooled ratio (medians over every fold's
  pairs at once). 1 = generated motion is as far from the person's unseen trials as those are
  from each other.
- **Identification**: a generated trial is identified when its mean EMD to its own person's
  held-out halves of the fold is below its mean EMD to the other person's held-out halves of
  the fold with the same index.
- **Fit time**: the longest fit of the run (seconds, wall clock on this machine).

Run: ``python benchmarks/generator_fidelity.py --part report`` (prints a Markdown table); give
``--symbols N`` or other settings (``--set emission=centroid``, the paper's synthesis and the
default before issue 38) to measure a variant.
"""

from __future__ import annotations

import argparse
import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mirror_avatar.common.seeds import draw_seeds
from mirror_avatar.datasets import BUNDLED_STYLES, load_zhai2017
from mirror_avatar.files.trials import Trial, make_trial
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.signatures.likeness import trial_velocity
from mirror_avatar.signatures.signature import compute_emd, compute_ims

RATE = 100.0
"""Rate (Hz) of the halves, the generators and the IMS."""

HALF_SECONDS = 30.0
"""Length (s) of each half trial."""

FOLDS = 8
"""Random partitions of each person's halves."""

N_FIT = 5
"""Halves a generator is fitted on in each fold (the other four are held out)."""

PARTS = {"development": 0, "report": 1, "whole": None}
"""Which half of every trial each part uses (``whole``: the 60 s trials, both halves)."""

Array = np.ndarray
Factory = Callable[[int], Any]


@dataclass
class PersonResult:
    """One person's folds: the ratio of each, identification and fit times."""

    person: str
    ratios: list[float]
    generated_to_held: list[float]
    held_to_held: list[float]
    identified: list[bool]
    fit_seconds: list[float]

    def row(self) -> dict[str, Any]:
        """Summarise the person: the fold ratios' median and range, the pooled ratio, etc."""
        return {
            "person": self.person,
            "ratio_median": float(np.median(self.ratios)),
            "ratio_min": float(np.min(self.ratios)),
            "ratio_max": float(np.max(self.ratios)),
            "ratio_pooled": float(np.median(self.generated_to_held) / np.median(self.held_to_held)),
            "generated_to_held": float(np.median(self.generated_to_held)),
            "held_to_held": float(np.median(self.held_to_held)),
            "identified": f"{sum(self.identified)} of {len(self.identified)}",
            "fit_s_max": float(np.max(self.fit_seconds)),
        }


def halves(part: str) -> dict[str, list[Trial]]:
    """Each person's trials of ``part``: ``development`` first 30 s, ``report`` last, or whole."""
    which = PARTS[part]
    size = int(HALF_SECONDS * RATE)
    if which is None:
        which, size = 0, int(2 * HALF_SECONDS * RATE) + 1
    people: dict[str, list[Trial]] = {style: [] for style in BUNDLED_STYLES}
    for trial in load_zhai2017():
        full = trial.resampled(RATE)
        window = slice(which * size, which * size + size)
        times = full.times[window] - full.times[window][0]
        people[trial.group].append(
            make_trial(
                times, full.positions[window], label=f"{trial.label}/{part}", group=trial.group
            )
        )
    return people


def partitions(n: int, folds: int, seed: int) -> list[tuple[list[int], list[int]]]:
    """``folds`` random splits of ``range(n)``: `N_FIT` indices to fit, the rest held out."""
    rng = np.random.default_rng(seed)
    splits = []
    for _ in range(folds):
        order = rng.permutation(n)
        splits.append((sorted(order[:N_FIT].tolist()), sorted(order[N_FIT:].tolist())))
    return splits


def ims(trial: Trial) -> Array:
    """Compute the velocity IMS of a trial at `RATE`."""
    return compute_ims(trial_velocity(trial, RATE))


def evaluate(factory: Factory, part: str, folds: int = FOLDS, seed: int = 0) -> list[PersonResult]:
    """Run the protocol for the generator ``factory(seed)`` makes (unfitted, `fit` / `sample`)."""
    people = halves(part)
    duration = HALF_SECONDS * (2 if PARTS[part] is None else 1)
    names = list(people)
    held_ims: dict[str, list[list[Array]]] = {name: [] for name in names}
    generated_ims: dict[str, list[list[Array]]] = {name: [] for name in names}
    results = {}
    for p, name in enumerate(names):
        trials = people[name]
        ratios, to_held, within, seconds = [], [], [], []
        splits = partitions(len(trials), folds, seed + 1000 * p)
        for (fit, held), fold_seed in zip(splits, draw_seeds([seed, p], folds), strict=True):
            start = time.perf_counter()
            model = factory(fold_seed).fit([trials[i] for i in fit])
            seconds.append(time.perf_counter() - start)
            generated = model.sample(duration, n=len(held), random_state=fold_seed)
            target = [ims(trials[i]) for i in held]
            made = [ims(g) for g in generated]
            pairs = [compute_emd(g, h) for g in made for h in target]
            own = [compute_emd(a, b) for a, b in itertools.combinations(target, 2)]
            ratios.append(float(np.median(pairs) / np.median(own)))
            to_held += pairs
            within += own
            held_ims[name].append(target)
            generated_ims[name].append(made)
        results[name] = PersonResult(name, ratios, to_held, within, [], seconds)
    for name in names:
        for k, made in enumerate(generated_ims[name]):
            for g in made:
                distance = {
                    other: np.mean([compute_emd(g, h) for h in held_ims[other][k]])
                    for other in names
                }
                results[name].identified.append(min(distance, key=distance.__getitem__) == name)
    return list(results.values())


def markdown(results: Sequence[PersonResult], title: str) -> str:
    """Write a Markdown table of `PersonResult.row` for each person, under ``title``."""
    rows = [r.row() for r in results]
    columns = list(rows[0])
    lines = [f"**{title}**", "", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for row in rows:
        cells = [f"{v:.4g}" if isinstance(v, float) else str(v) for v in row.values()]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--part", choices=list(PARTS), default="development")
    parser.add_argument("--folds", type=int, default=FOLDS)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--symbols", default="auto", help="codebook size or auto")
    parser.add_argument(
        "--set",
        nargs="*",
        default=[],
        metavar="NAME=VALUE",
        help="other generator settings, e.g. window=80 emission=centroid",
    )
    args = parser.parse_args()
    settings: dict[str, Any] = {
        "n_symbols": args.symbols if args.symbols == "auto" else int(args.symbols)
    }
    for item in args.set:
        key, _, value = item.partition("=")
        settings[key] = _number(value)
    results = evaluate(
        lambda seed: IMSGenerator(random_state=seed, **settings), args.part, args.folds, args.seed
    )
    described = ", ".join(f"{k}={v}" for k, v in settings.items())
    title = f"{args.part} halves, {args.folds} folds, seed {args.seed}; {described}"
    print(markdown(results, title))


def _number(value: str) -> int | float | str:
    """Read a setting's value: a whole number, a real number, or else the text itself."""
    for kind in (int, float):
        try:
            return kind(value)
        except ValueError:
            pass
    return value


if __name__ == "__main__":
    main()
