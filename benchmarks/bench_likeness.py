"""Human-likeness and groups of people on the bundled trials (issue 38's must-show).

The battery (`mirror_avatar.signatures.likeness.compare_motion`, seed 0) on the bundled trials
resampled to 100 Hz: odd against even trials of one style (held-out trials of one person against
each other), the first four fast trials against the last five, and fast against slow; each row the
classifier's AUC with its permutation p-value and the IMS EMD ratio, and the battery's time. Then
`signature --groups`'s comparison (`mirror_avatar.signatures.groups.compare_groups`) of fast and
slow trials, each taken as a person, with the true labels and with labels shuffled within each
style.
"""

from __future__ import annotations

import time

import numpy as np

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.signatures.groups import compare_groups
from mirror_avatar.signatures.likeness import compare_motion, trial_velocity
from mirror_avatar.signatures.signature import analyse_signatures


def run(quick: bool) -> list[dict]:
    trials = load_zhai2017()
    velocity = {t.label: trial_velocity(t) for t in trials}
    fast = [velocity[f"fast-{k}"] for k in range(1, 10)]
    slow = [velocity[f"slow-{k}"] for k in range(1, 10)]
    pairs = {
        "fast odd vs even trials": (fast[::2], fast[1::2]),
        "slow odd vs even trials": (slow[::2], slow[1::2]),
        "fast trials 1-4 vs 5-9": (fast[:4], fast[4:]),
        "fast vs slow trials": (fast, slow),
    }
    rows = []
    for name, (a, b) in pairs.items():
        start = time.perf_counter()
        result = compare_motion(a, b, seed=0)
        seconds = time.perf_counter() - start
        emd = result.distances[0]
        rows.append(
            {
                "name": f"classifier AUC, {name}",
                "value": result.classifier.auc,
                "unit": "AUC",
                "note": f"p = {result.classifier.test.p_value:.3g} (null "
                f"{np.mean(result.classifier.test.null):.2f} +- "
                f"{np.std(result.classifier.test.null):.2f}); IMS EMD {emd.ratio:.2f} x own "
                f"(p = {emd.test.p_value:.3g}); battery {seconds:.1f} s; {result.verdict()}",
            }
        )
    analysis = analyse_signatures(trials)
    people = analysis.labels
    styles = [t.group for t in trials]
    rng = np.random.default_rng(7)
    shuffled = [*rng.permutation(["a"] * 5 + ["b"] * 4), *rng.permutation(["a"] * 4 + ["b"] * 5)]
    for name, groups, order in (
        ("fast vs slow people", styles, ["fast", "slow"]),
        ("labels shuffled within each style", shuffled, ["a", "b"]),
    ):
        comparison = compare_groups(analysis.emd, people, groups, order, seed=0)
        c = comparison.classification
        rows.append(
            {
                "name": f"leave-one-person-out accuracy, {name}",
                "value": c.accuracy,
                "unit": "share",
                "baseline": float(np.mean(comparison.chance.null)),
                "note": f"baseline = label-shuffled chance; p = {comparison.chance.p_value:.3g}; "
                f"sensitivity {c.sensitivity:.2f}, specificity {c.specificity:.2f}; EMD between "
                f"{comparison.between:.4f}, within {comparison.within:.4f} "
                f"(p = {comparison.separation.p_value:.3g})",
            }
        )
    return rows
