"""A person's avatar from their solo trials, validated as the paper's Table I (METHODS 10).

`create_avatar` fits the person's motion model (a stroke generator, the default kind of
`mirror_avatar.motion.models`: it chains the person's own strokes), makes
their virtual trainer, trains a cyber player to imitate it as follower and as leader on sessions
it plays with the training partners (`mirror_avatar.experiments.cyber_player.run_role`, the
paper's set-up with the person as the target), and validates each closed-loop against the
person's own virtual trainer with every partner, the last one never met in training: CV, RMS and
EMD per partner, the reproduction criteria, and the baselines. Then the avatar is checked against
the person themselves (`mirror_avatar.experiments.avatar_proof`): each trial held out in turn from
an avatar built without it, in every role (`mirror_avatar.experiments.avatar_holdout`), and the
person's sessions with a partner replayed against the avatar. The result is one `Avatar` and a
report `Section` (the avatar's card), a verdict for each role first.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.experiments.avatar_holdout import (
    Fold,
    RoleMotion,
    build_fold,
    dyad_motion,
    make_folds,
    play_group,
    prove_held_out,
    split_held_out,
)
from mirror_avatar.experiments.avatar_proof import PartnerSession, Proof, prove_with_partners
from mirror_avatar.experiments.cyber_player import (
    BASELINE_SESSIONS,
    CRITERIA,
    VALIDATION_SESSIONS,
    RoleResult,
    check_criteria,
    make_table_one,
    run_role,
)
from mirror_avatar.figures.learning import plot_learning_curves
from mirror_avatar.figures.signatures import plot_ims
from mirror_avatar.files.atomic import write_atomic_text
from mirror_avatar.files.trials import DEFAULT_RATE, Trial
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.motion.models import MotionModel, kind_of
from mirror_avatar.motion.strokes import StrokeGenerator
from mirror_avatar.report import Section, render_report
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.signature import DEFAULT_BINS, compute_ims
from mirror_avatar.training.agents import AGENT_NAMES
from mirror_avatar.training.avatar import Avatar
from mirror_avatar.training.cast import Cast, VirtualTrainerSpec, make_virtual_trainers
from mirror_avatar.training.imitation import Agent, Role

ROLES: tuple[Role, ...] = ("follower", "leader")
"""The roles trained, those of `mirror_avatar.training.avatar.TRAINED_ROLES`."""

DEFAULT_SESSIONS = 8000
"""Training sessions per role of tabular players (**choice**, twice the paper's 4000: with fewer,
a follower's CV against a partner unseen in training stayed well below its person's; ``make
bench``, ``avatar``, measures the time and the validation at this default)."""

DEFAULT_DQN_SESSIONS = 300
"""Training sessions per role of deep players (**choice**: those of the Table I experiment,
`mirror_avatar.experiments.cyber_player.TRAINING_SESSIONS`)."""


def create_avatar(
    trials: Sequence[Trial],
    name: str,
    partners: Sequence[tuple[str, MotionModel]],
    n_sessions: int | None = None,
    n_validation: int = VALIDATION_SESSIONS,
    n_baseline: int = BASELINE_SESSIONS,
    seed: int = 0,
    n_jobs: int = 2,
    progress: Callable[[str], None] | None = None,
    agent: Agent = "tabular",
    n_held_out: int | None = None,
    partner_sessions: Sequence[PartnerSession] = (),
    scheduler: str | None = None,
) -> tuple[Avatar, Section]:
    """Build and validate a person's avatar.

    Parameters
    ----------
    trials
        The person's solo trials (any rate; at least one), held-out ones included.
    name
        Whom the avatar stands for.
    partners
        (label, motion model) of the partners: all but the last train the avatar, the last is
        met only in validation (at least two).
    n_sessions, n_validation, n_baseline
        Training sessions per role (default `DEFAULT_SESSIONS`, or `DEFAULT_DQN_SESSIONS`
        for deep players); validation sessions per partner and role; held-out sessions of the
        baselines.
    seed
        Seeds the motion model, training, validation and baselines (recorded in the avatar).
    n_jobs
        Local threads generating training sessions.
    progress
        Called with the name of each stage as it begins.
    agent
        ``"tabular"`` (Q-tables) or ``"dqn"`` (deep Q-networks) for both roles.
    n_held_out
        Trials kept out of fitting the avatar itself, in one split, for the proof
        (`split_held_out`; 0: no proof). Default: the avatar is fitted on every trial, and
        each is held out in turn from an avatar built the same way
        (`mirror_avatar.experiments.avatar_holdout.make_folds`).
    partner_sessions
        Dyad sessions the person played, replayed against the avatar for the proof.
    scheduler
        Address of a Dask scheduler (``tcp://host:port``) whose workers play the training and
        baseline sessions instead of local threads (the same avatar either way).

    Raises
    ------
    InputError
        Fewer than two partners, a held-out count leaving nothing to fit, or trials the
        stroke generator cannot be fitted on.
    """
    if len(partners) < 2:
        raise InputError("--partners", "give at least two partners: the last is kept unseen")
    report = progress or (lambda stage: None)
    if n_sessions is None:
        n_sessions = DEFAULT_DQN_SESSIONS if agent == "dqn" else DEFAULT_SESSIONS
    fitted, held_out = (
        (list(trials), []) if n_held_out is None else split_held_out(trials, n_held_out)
    )
    report("fitting the stroke generator")
    generator = StrokeGenerator(rate=DEFAULT_RATE, random_state=seed).fit(fitted)
    trainers = [VirtualTrainerSpec(label, (), model) for label, model in partners]
    person = VirtualTrainerSpec(name, tuple(t.label for t in fitted), generator)
    n = len(trainers)
    cast = Cast([*trainers, person], n, tuple(range(n - 1)), n - 1, True)
    results = []
    for role in ROLES:
        report(f"training and validating the {role}")
        results.append(
            run_role(
                cast, role, n_sessions, n_validation, n_baseline, seed, n_jobs, agent, scheduler
            )
        )
    criteria: dict[str, pd.DataFrame] = {r.role: check_criteria(r) for r in results}
    summary = _summary(results, criteria, cast, generator, n_sessions, n_validation, seed)
    summary["agent"] = agent
    avatar = Avatar(name, generator, {r.role: r.player for r in results}, summary)
    folds = []
    if held_out:
        report("checking the avatar against the person")
        folds.append(_own_fold(cast, results, held_out, n_validation, seed))
    elif n_held_out is None:
        folds = _cross_validate(
            cast, trials, (n_sessions, n_validation), seed, n_jobs, agent, scheduler, report
        )
    proof = Proof(
        prove_held_out(trials, folds, 1.0 / results[0].player.period, seed) if folds else None,
        prove_with_partners(avatar, partner_sessions, seed=seed) if partner_sessions else None,
        _example(folds),
    )
    summary["proof"] = proof.to_json_dict()
    table = pd.concat(criteria)
    met = f"criteria met for {int(table['all'].sum())} of {len(table)} role and partner pairs"
    summary["verdict"] = f"The avatar {proof.verdict()}; {met}."
    return avatar, make_card(avatar, results, criteria, proof)


def _example(folds: Sequence[Fold]) -> tuple[Trial, Session] | None:
    """Return the first fold's first held-out trial and a session its avatar played as leader."""
    if not folds or folds[0].example is None:
        return None
    return folds[0].held_out[0], folds[0].example


def _cross_validate(
    cast: Cast,
    trials: Sequence[Trial],
    sessions: tuple[int, int],
    seed: int,
    n_jobs: int,
    agent: Agent,
    scheduler: str | None,
    report: Callable[[str], None],
) -> list[Fold]:
    """Hold every trial out in turn (`make_folds`), each fold an avatar built without it."""
    folds = []
    indices = make_folds(len(trials))
    for k, left in enumerate(indices):
        report(
            f"checking against the person: fold {k + 1} of {len(indices)}, an avatar built "
            f"without {', '.join(trials[i].label for i in left)}"
        )
        kept = [t for i, t in enumerate(trials) if i not in left]
        held = [trials[i] for i in left]
        folds.append(build_fold(cast, kept, held, sessions, seed, n_jobs, agent, scheduler))
    return folds


def _own_fold(
    cast: Cast,
    results: Sequence[RoleResult],
    held_out: Sequence[Trial],
    n_validation: int,
    seed: int,
) -> Fold:
    """Make the avatar itself the check's one fold: its validation, and groups played anew."""
    motion: dict[str, RoleMotion] = {r.role: dyad_motion(r.velocities, r.target) for r in results}
    follower, leader = (next(r for r in results if r.role == role) for role in ROLES)
    motion["group member"] = play_group(cast, follower.player, n_validation, seed)
    return Fold(list(held_out), motion, leader.example[1])


def save_avatar(avatar: Avatar, card: Section, path: Path, metadata: dict[str, Any]) -> Path:
    """Write the avatar file and its card beside it (``.html``, with ``metadata``).

    Returns the card's path.
    """
    avatar.save(path)
    card_path = avatar_card_path(path)
    page = render_report(
        [card], f"Avatar of {avatar.name}", metadata, lead=avatar.summary.get("verdict", "")
    )
    write_atomic_text(card_path, page)
    return card_path


def avatar_card_path(path: Path) -> Path:
    """Where `save_avatar` writes the card of the avatar file ``path``: the same name, ``.html``."""
    return path.with_suffix(".html")


def default_partners(seed: int) -> list[tuple[str, MotionModel]]:
    """Make the bundled library of partners: VT1..VT6, each fitted on 3 trials of a style.

    VT1..VT5 train the avatar and VT6 is kept unseen, as in the paper's set-up
    (`mirror_avatar.training.cast.make_virtual_trainers`).
    """
    trainers = make_virtual_trainers(load_zhai2017(), seed=seed)
    return [(f"{t.label} ({', '.join(t.trial_labels)})", t.generator) for t in trainers]


def make_card(
    avatar: Avatar,
    results: Sequence[RoleResult],
    per_role: dict[str, pd.DataFrame],
    proof: Proof,
) -> Section:
    """Make the avatar's card: a verdict per role, IMS, validation tables, criteria, curves.

    ``per_role`` holds each role's `check_criteria` table; ``proof`` the check against the
    person. The summary's one-line ``verdict`` leads the page (`save_avatar`); the card's text
    opens with a sentence for each role the avatar plays.
    """
    person_ims = compute_ims(np.concatenate([v for r in results for v in r.velocities[r.target]]))
    avatar_ims = compute_ims(
        np.concatenate([v for r in results for v in r.velocities["cyber player"]])
    )
    criteria = pd.concat(per_role)
    partners = [_short(p) for p in avatar.summary["partners"]]
    unseen = ", ".join(
        f"{role} CV {r['unseen_cv_difference']:+.3f}, RMS {r['unseen_rms_difference']:+.3f}, "
        f"EMD to {avatar.name} {r['emd_to_person']:.4f}"
        for role, r in avatar.summary["roles"].items()
    )
    held = proof.held_out
    text = (
        [held.role_verdict(r) for r in held.to_avatar]
        if held
        else [f"The avatar {proof.verdict()}."]
    )
    text += [
        f"{avatar.name}'s {describe_model(avatar.generator)}; their "
        f"{AGENT_NAMES[avatar.summary.get('agent', 'tabular')]} "
        f"learned to move like their virtual trainer as follower and as leader, playing with "
        f"{', '.join(partners[:-1])}. Each partner then played the same seeded sessions with "
        f"the person's virtual trainer and with the avatar; {partners[-1]} was never met in "
        "training. In a group the avatar plays its follower policy.",
        f"Against the unseen partner, the avatar's difference from the person's virtual "
        f"trainer: {unseen}. The paper's reproduction criteria (CV and RMS within "
        f"{CRITERIA['max_difference']:g} of the person's, CV at least {CRITERIA['min_cv']:g}, "
        f"RMS at most {CRITERIA['max_rms']:g}, EMD at most {CRITERIA['max_emd_to_target']:g}) "
        f"are met for {int(criteria['all'].sum())} of {len(criteria)} role and partner pairs.",
        _describe_check(proof),
    ]
    figures: dict[str, Any] = {
        f"Velocity IMS of {avatar.name}'s virtual trainer and of the avatar (validation)": plot_ims(
            {f"{avatar.name} (virtual trainer)": person_ims, "avatar": avatar_ims}, DEFAULT_BINS
        ),
    }
    trace = proof.plot_trace(avatar.name)
    if trace is not None:
        figures[f"{avatar.name} against the avatar (positions)"] = trace
    for result in results:
        figures[f"Learning curve, {result.role}"] = plot_learning_curves(
            {"cyber player": (result.curve.sessions, result.curve.rms)},
            {f"{k} (held out)": v for k, v in result.baselines.items()},
            title=f"Learning to imitate {avatar.name} as {result.role}",
        )
    return Section(
        key="avatar",
        title=f"Avatar of {avatar.name}",
        text=text,
        tables=proof.tables()
        | {
            f"Table I: {avatar.name}'s virtual trainer and the avatar against each partner, "
            "mean \N{PLUS-MINUS SIGN} SD over the sessions": _table_one(results),
            "The paper's reproduction criteria per role and partner": _criteria_table(criteria),
            "RMS (units) to the person's virtual trainer on held-out sessions": pd.DataFrame(
                {r.role: r.baselines for r in results}
            ).T.rename(columns=BASELINE_HEADERS),
        },
        figures=figures,
        metrics=avatar.summary,
    )


BASELINE_HEADERS = {
    "trained": "the trained avatar",
    "untrained (random Q)": "an untrained one (random Q)",
    "copy the partner": "copying the partner",
}
"""The card's headers of the baselines (`compare_baselines`)."""

CRITERIA_NAMES = {
    "cv within": f"CV within {CRITERIA['max_difference']:g}",
    "rms within": f"RMS within {CRITERIA['max_difference']:g}",
    "cv >= min": f"CV at least {CRITERIA['min_cv']:g}",
    "rms <= max": f"RMS at most {CRITERIA['max_rms']:g}",
    "emd <= max": f"EMD at most {CRITERIA['max_emd_to_target']:g}",
}
"""Each criterion of `check_criteria` in words."""


def _describe_check(proof: Proof) -> str:
    """How the avatar was checked against the person, in words."""
    held = proof.held_out
    how = "No solo trial was held out of fitting." if held is None else (
        f"{held.explain_scheme()} Each held-out trial's velocity IMS is compared (EMD) with each "
        "session an avatar built without it played as follower and as leader with every "
        "partner, and as a group member; a role is flagged when the median of those EMDs is "
        "above the 95th percentile of the person's own trial-to-trial EMD (every pair of their "
        "trials). The person's virtual trainer in the same sessions shows how far the role "
        "itself moves anyone from a solo trial."
    )  # fmt: skip
    if proof.partners is not None:
        how += (
            " Sessions the person played with a partner are played again by the avatar in "
            "their place against the partner's recorded track."
        )
    return how


def _table_one(results: Sequence[RoleResult]) -> pd.DataFrame:
    """Table I (`make_table_one`) with headers in words and short partner names."""
    table = pd.concat([make_table_one(r) for r in results])
    target = results[0].target
    who = {target: "the person's virtual trainer", "cyber player": "the avatar"}
    measure = {"EMD": "EMD to the partner", "CV": "CV", "RMS": "RMS (units)"}
    table.columns = [
        f"{measure[m]}, {who[name]}" for m, name in (c.split(" ", 1) for c in table.columns)
    ]
    table.index = pd.MultiIndex.from_tuples([(role, _short(p)) for role, p in table.index])
    return table.map(
        lambda cell: cell.replace(" +- ", "\N{NO-BREAK SPACE}\N{PLUS-MINUS SIGN}\N{NO-BREAK SPACE}")
    )


def _criteria_table(criteria: pd.DataFrame) -> pd.DataFrame:
    """Return the criteria (`check_criteria` by role) with headers in words."""
    numbers = criteria.iloc[:, :5]
    table = pd.DataFrame(
        numbers.to_numpy(),
        index=pd.MultiIndex.from_tuples([(role, _short(p)) for role, p in criteria.index]),
        columns=[
            "CV, the person's virtual trainer",
            "CV, the avatar",
            "RMS (units), the person's virtual trainer",
            "RMS (units), the avatar",
            "EMD from the avatar to the virtual trainer",
        ],
    )
    table["criteria met"] = [
        "all"
        if row["all"]
        else "no: " + ", ".join(name for key, name in CRITERIA_NAMES.items() if not row[key])
        for _, row in criteria.iterrows()
    ]
    return table


def _short(label: str) -> str:
    """Name a partner on the card: a file given by its path by its file name."""
    return Path(label).name if "/" in label else label


def _summary(
    results: Sequence[RoleResult],
    per_role: dict[str, pd.DataFrame],
    cast: Cast,
    generator: MotionModel,
    n_sessions: int,
    n_validation: int,
    seed: int,
) -> dict[str, Any]:
    """How the avatar was made and how it validated, for its file and its card."""
    roles = {}
    for result in results:
        criteria = per_role[result.role]
        unseen = criteria.iloc[-1]
        roles[result.role] = {
            "emd_to_person": float(unseen[f"emd to {result.target}"]),
            "unseen_cv_difference": float(unseen["cv cyber"] - unseen[f"cv {result.target}"]),
            "unseen_rms_difference": float(unseen["rms cyber"] - unseen[f"rms {result.target}"]),
            "criteria_met": bool(criteria["all"].all()),
            "per_partner": criteria.drop(columns="all").to_dict(orient="index"),
        }
    summary: dict[str, Any] = {
        "partners": [t.label for t in cast.trainers[:-1]],
        "unseen_partner": cast.trainers[cast.unseen].label,
        "trials": generator.training_summary_["labels"],
        "generator": kind_of(generator),
    }
    if isinstance(generator, IMSGenerator):
        summary["n_symbols"] = generator.n_symbols_
    return summary | {
        "n_sessions": n_sessions,
        "n_validation": n_validation,
        "seed": seed,
        "roles": roles,
    }


def describe_model(model: MotionModel) -> str:
    """Say what a person's motion model is and what it was fitted on, for the card."""
    summary = model.training_summary_
    n_trials = len(summary["labels"])
    if isinstance(model, StrokeGenerator):
        return f"stroke generator was fitted on {n_trials} trials ({summary['n_strokes']} strokes)"
    rule = summary["complexity"]["rule"]
    return f"IMS generator was fitted on {n_trials} trials with {model.n_symbols_} symbols ({rule})"
