"""The reproduction report's answers: one line per experiment, and the run's mode in words.

Each verdict is read from its section's metrics (the experiments keep their own prose), so that
the report's contents say at a glance what every validation found.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import ModuleType
from typing import Any

from mirror_avatar.experiments import cyber_player, group
from mirror_avatar.learning.acceleration_player import Agent

Metrics = Mapping[str, Any]


def section_verdict(key: str, metrics: Metrics) -> str:
    """One line saying what the experiment ``key`` found.

    Empty for an experiment this module does not know, and for one skipped for want of data
    (its metrics lack the numbers the verdict reads).
    """
    read = VERDICTS.get(key)
    try:
        return read(metrics) if read is not None else ""
    except (KeyError, ZeroDivisionError):
        return ""


def describe_mode(quick: bool, full: bool, agent: Agent) -> str:
    """Say the run's size in words: what ``--quick`` and ``--full`` changed, what to run next.

    Parameters
    ----------
    quick, full
        The options ``reproduce`` was given.
    agent
        The cyber players' agent, whose training sessions the quick size cuts.
    """
    if quick:
        return (
            "A quick run (--quick): every experiment at a small size, the cyber players trained "
            f"{cyber_player.QUICK_TRAINING_SESSIONS[agent]} sessions instead of "
            f"{cyber_player.TRAINING_SESSIONS[agent]}, so the cyber players' criteria are not "
            "expected to be met; for the paper's sizes run reproduce without --quick, and with "
            "--full for the long sweeps too."
        )
    if full:
        return "A full run (--full): every experiment and the long sweeps at full size."
    return (
        "The experiments at full size; the long sweeps (the generator's codebook from a few "
        "trials and the curriculum) at their quick size: give --full to run them at full size."
    )


def _signature(m: Metrics) -> str:
    distinct, ratio = m["styles_distinct"], m["between_within_ratio"]
    if distinct is None:
        return (
            f"EMD between groups {ratio:.1f} x within; no verdict on the regions (each half of "
            "a group needs 3 trials)"
        )
    told = "told apart" if distinct else "NOT told apart"
    return (
        f"the {len(m['groups'])} groups are {told}: their regions overlap at most "
        f"{m['max_between_overlap']:.2f}, a group with its own halves at least "
        f"{m['min_half_overlap']:.2f}; EMD between groups {ratio:.1f} x within"
    )


def _generator(m: Metrics) -> str:
    checks = m["checks"]
    failed = [name.replace("_", " ") for name, passed in checks.items() if not passed]
    line = f"generated motion passes {len(checks) - len(failed)} of {len(checks)} checks"
    return (
        line
        + (f" (fails: {', '.join(failed)})" if failed else "")
        + (f"; {m['identification_accuracy']:.0%} of generated trials identified as their style")
    )


def _generator_complexity(m: Metrics) -> str:
    rows = [row for row in m["table"] if row["method"].startswith("chosen")]
    ratios = [row["EMD ratio (mean)"] for row in rows]
    identified = sum(row["identified"] for row in rows) / len(rows)
    return (
        f"with the codebook chosen from the data, generated motion is {min(ratios):.2f} to "
        f"{max(ratios):.2f} x as far from unseen trials as the person's own trials (1: as "
        f"close); {identified:.0%} identified as their style"
    )


def _virtual_trainer(m: Metrics) -> str:
    follows, leads = m["summary"]["follows"], m["summary"]["leads"]
    return (
        f"following people CV {follows['cv']:.2f} (paper {follows['paper_cv']:g}), RMS "
        f"{follows['rmse']:.3f} units (paper {follows['paper_rmse']:g}); leading CV "
        f"{leads['cv']:.2f} (paper {leads['paper_cv']:g})"
    )


def _cyber_player(m: Metrics) -> str:
    roles = []
    for role in ("follower", "leader"):
        criteria = m[role]["criteria"]
        met = sum(bool(row["all"]) for row in criteria.values())
        roles.append(f"as {role} against {met} of {len(criteria)} partners")
    return "reproduction criteria met " + ", ".join(roles) + _training(m, cyber_player)


def _group(m: Metrics) -> str:
    criteria, limit = m["criteria"], group.CRITERIA["max_difference"]
    differences = ", ".join(
        f"{name} {criteria[f'{key} difference']:+.3f}"
        for key, name in (
            ("phase_locking", "CV"),
            ("group_synchronisation", "sync"),
            ("rmse", "RMS"),
        )  # fmt: skip
    )
    met = "met" if criteria["all"] else "NOT met"
    return f"criteria {met} (within {limit:g} of the target's: {differences})" + _training(m, group)


def _curriculum(m: Metrics) -> str:
    own = m["own_emd"]
    lines = []
    for method in dict.fromkeys(row["method"] for row in m["stages"]):
        stages = [row for row in m["stages"] if row["method"] == method]
        starts = stages[0]["EMD to patient"] <= own["patient"]
        ends = stages[-1]["EMD to target"] <= own["target"]
        start = "starts" if starts else "does NOT start"
        end = "ends within" if ends else "does NOT end within"
        lines.append(f"{method} {start} within the patient's variability, {end} the target's")
    return "; ".join(lines)


def _training(m: Metrics, experiment: ModuleType) -> str:
    """Say that the player trained fewer sessions than the experiment's full size."""
    sessions, full = m["training_sessions"], experiment.TRAINING_SESSIONS[m["agent"]]
    return f" (trained {sessions} sessions, a quick run; full: {full})" if sessions < full else ""


VERDICTS: dict[str, Callable[[Metrics], str]] = {
    "signature": _signature,
    "generator": _generator,
    "generator_complexity": _generator_complexity,
    "virtual_trainer": _virtual_trainer,
    "cyber_player": _cyber_player,
    "group": _group,
    "curriculum": _curriculum,
}
"""Section key -> the function reading its verdict from its metrics."""
