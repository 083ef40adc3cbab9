"""Validation of the cyber player (paper Tables I-II, figures 8-9; METHODS section 7).

A cyber player is trained to imitate a target virtual trainer (VT5 of the bundled data, see
`mirror_avatar.training.cast.cast_virtual_trainers`) as a follower and as a leader, then
replaces it and plays closed-loop (in the compiled loop,
`mirror_avatar.engine.batch.play_compiled`) with the training partners and one partner never met
in training. Each partner plays the same seeded sessions with the target and with the cyber
player, so CV and RMS can be compared by paired t-tests (the paper finds no significant
difference, all p > 0.05). Also reported: EMD of each player's velocity signature to the
partner's, the similarity-space regions of the target, the cyber player and the partners with
their overlaps, example position time series, learning curves, and a baseline comparison on
held-out sessions: RMS to the target of the trained player, of an untrained one (random Q) and of
simply copying the partner. One module for one experiment: its runs, tables and text.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from mirror_avatar.common.seeds import draw_seeds
from mirror_avatar.engine.batch import play_compiled, run_sessions
from mirror_avatar.engine.loop import count_samples
from mirror_avatar.figures.learning import plot_learning_curves
from mirror_avatar.figures.sessions import plot_positions
from mirror_avatar.figures.signatures import plot_similarity_space
from mirror_avatar.files.trials import Trial
from mirror_avatar.learning.acceleration_player import AccelerationPlayer
from mirror_avatar.learning.training import LearningCurve
from mirror_avatar.metrics import TRIM, paired_ttest, session_metrics
from mirror_avatar.report import Section
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.signature import (
    classical_mds,
    compute_emd,
    compute_emd_matrix,
    compute_ims,
    confidence_ellipse,
    ellipse_overlap,
)
from mirror_avatar.training.agents import AGENT_NAMES
from mirror_avatar.training.cast import Cast, cast_virtual_trainers
from mirror_avatar.training.imitation import (
    TRAINING_ROLES,
    Agent,
    Role,
    derive_seeds,
    make_cyber_player,
    make_pairs,
    score_avatar,
    train_cyber_player,
)

TRAINING_SESSIONS: dict[Agent, int] = {"tabular": 4000, "dqn": 300}
"""Training sessions per role by default, per agent (**choice**: enough for both roles to match
the target while keeping ``make demo`` to a few minutes, the paper used about 24 000; a DQN
update every step learns from far fewer sessions than the table, ``benchmarks/bench_deep.py``
measures both)."""

QUICK_TRAINING_SESSIONS: dict[Agent, int] = {"tabular": 300, "dqn": 40}
VALIDATION_SESSIONS = 20
"""Sessions per partner and role in validation (the paper's 20)."""

QUICK_VALIDATION_SESSIONS = 4
BASELINE_SESSIONS = 100
"""Held-out virtual-trainer sessions for the baseline comparison."""

QUICK_BASELINE_SESSIONS = 20

SESSION_SECONDS = 60.0
"""Length of a validation session (s)."""

PAPER = {"cv": (0.74, 0.90), "rms": (0.10, 0.12), "emd": (0.002, 0.008)}
"""The paper's Table I ranges."""

CRITERIA = {"max_difference": 0.05, "min_cv": 0.75, "max_rms": 0.15, "max_emd_to_target": 0.01}
"""The reproduction criteria checked per partner: the cyber player's mean CV and RMS each
within ``max_difference`` of the target's, its CV at least ``min_cv`` and RMS at most
``max_rms``, and its velocity IMS within EMD ``max_emd_to_target`` of the target's (over all
sessions of the role)."""


@dataclass
class RoleResult:
    """Everything measured for one role: training, closed-loop validation and baselines."""

    role: Role
    target: str
    unseen: str
    player: AccelerationPlayer
    curve: LearningCurve
    train_seconds: float
    records: pd.DataFrame
    velocities: dict[str, list[np.ndarray]]
    example: tuple[Session, Session]
    baselines: dict[str, float]


def run(
    trials: Sequence[Trial],
    quick: bool = False,
    seed: int = 0,
    n_sessions: int | None = None,
    n_validation: int | None = None,
    n_jobs: int = 2,
    agent: Agent = "tabular",
    scheduler: str | None = None,
) -> Section:
    """Train the cyber player as follower and leader and validate it against its target.

    Parameters
    ----------
    trials
        Solo trials; the virtual trainers are made from them (`cast_virtual_trainers`: VT5 of
        six blocks for the bundled data, one per person for three people or more).
    quick
        Fewer training sessions (`QUICK_TRAINING_SESSIONS`) and validation sessions.
    seed
        Seeds the generators, the training runs, the validation and baseline sessions.
    n_sessions, n_validation
        Override the number of training sessions per role and validation sessions per partner.
    n_jobs
        Local threads generating training sessions.
    agent
        ``"tabular"`` (the paper's Q-table) or ``"dqn"`` (a deep Q-network).
    scheduler
        Address of a Dask scheduler (``tcp://host:port``) whose workers play the training and
        baseline sessions instead of local threads (the same sessions either way).

    Returns
    -------
    Section
        Tables I-II in the paper's layout, baselines, figures and metrics.
    """
    n_train = n_sessions or (QUICK_TRAINING_SESSIONS if quick else TRAINING_SESSIONS)[agent]
    n_valid = n_validation or (QUICK_VALIDATION_SESSIONS if quick else VALIDATION_SESSIONS)
    n_base = QUICK_BASELINE_SESSIONS if quick else BASELINE_SESSIONS
    cast = cast_virtual_trainers(trials, seed=seed)
    target = cast.trainers[cast.target].label
    results = [
        run_role(cast, role, n_train, n_valid, n_base, seed, n_jobs, agent, scheduler)
        for role in TRAINING_ROLES
    ]
    table_one = pd.concat([make_table_one(r) for r in results])
    table_two = pd.concat([make_table_two(r) for r in results])
    criteria = {r.role: check_criteria(r) for r in results}
    baselines = pd.DataFrame({r.role: r.baselines for r in results}).T
    regions = {r.role: compute_regions(r.velocities) for r in results}
    overlaps = pd.concat({role: reg[2] for role, reg in regions.items()})
    metrics = _metrics(results, table_one, table_two, overlaps, cast, seed, n_train, n_valid)
    metrics["agent"] = agent
    for role, checks in criteria.items():
        metrics[role]["criteria"] = checks.to_dict(orient="index")
    figures: dict[str, Any] = {}
    for result in results:
        points, ellipses, _ = regions[result.role]
        figures |= {
            f"Learning curve, {result.role} (dashed: baselines on held-out sessions)": (
                plot_learning_curves(
                    {"trained cyber player": (result.curve.sessions, result.curve.rms)},
                    {f"{k} (held out)": v for k, v in result.baselines.items()},
                    title=f"Learning to imitate {target} as {result.role}",
                )
            ),
            f"Similarity space, {result.role}: 70% regions of {target}, cyber player, partners": (
                plot_similarity_space(points, ellipses)
            ),
            f"Example positions, {result.role}, the first partner (first 20 s)": _plot_example(
                result, cast.trainers[cast.seen[0]].label
            ),
        }
    return Section(
        key="cyber_player",
        title=f"Cyber player: learning to move like {target} (Tables I-II)",
        text=_describe(results, table_two, cast, n_train, n_valid, agent),
        tables={
            f"Table I: {target} and the cyber player against each partner (mean +- SD)": table_one,
            f"Table II: paired t-tests, {target} vs cyber player": table_two,
            f"Reproduction criteria: cyber player vs {target}, per partner": pd.concat(criteria),
            f"RMS to {target} on held-out sessions (units): trained, untrained, copy partner": (
                baselines
            ),
            "Overlap of the similarity-space regions (intersection / union)": overlaps,
        },
        figures=figures,
        metrics=metrics,
    )


def run_role(
    cast: Cast,
    role: Role,
    n_train: int,
    n_valid: int,
    n_base: int,
    seed: int,
    n_jobs: int,
    agent: Agent = "tabular",
    scheduler: str | None = None,
) -> RoleResult:
    """Train for ``role``, then validate closed-loop and against the baselines.

    Sessions are played on the Dask cluster at ``scheduler`` when one is given.
    """
    target = cast.trainers[cast.target]
    start = time.perf_counter()
    player, curve = train_target(cast, role, n_train, seed, n_jobs, agent, scheduler)
    seconds = time.perf_counter() - start
    records, velocities, example = validate(player, cast, role, n_valid, seed)
    baselines = compare_baselines(player, cast, role, n_base, seed, n_jobs, scheduler)
    unseen = cast.trainers[cast.unseen].label
    return RoleResult(
        role, target.label, unseen, player, curve, seconds, records, velocities, example, baselines
    )


def train_target(
    cast: Cast,
    role: Role,
    n_train: int,
    seed: int,
    n_jobs: int,
    agent: Agent = "tabular",
    scheduler: str | None = None,
) -> tuple[AccelerationPlayer, LearningCurve]:
    """Train a cyber player to move like the cast's target in ``role``, against its seen partners.

    Sessions are played on the Dask cluster at ``scheduler`` when one is given.
    """
    return train_cyber_player(
        cast.trainers[cast.target].generator,
        [cast.trainers[i].generator for i in cast.seen],
        role=role,
        n_sessions=n_train,
        seed=seed,
        scheduler=scheduler,
        n_jobs=n_jobs,
        agent=agent,
    )


def validate(
    player: AccelerationPlayer, cast: Cast, role: Role, n_sessions: int, seed: int
) -> tuple[pd.DataFrame, dict[str, list[np.ndarray]], tuple[Session, Session]]:
    """Play each partner against the target and against the cyber player, the same seeds for both.

    The partner (player 0) takes the other role's preset; the target or the cyber player is
    player 1.

    Returns
    -------
    records : DataFrame
        One row per session: partner, player (the target's label or ``"cyber player"``),
        session index, ``cv``, ``rms`` (to the partner, units), ``emd`` (velocity IMS to the
        partner's).
    velocities : dict
        The target's label, ``"cyber player"``, ``"partners"`` -> each session's velocity
        (units/s) after the transient (partners: from the target's sessions).
    example : tuple of Session
        The first session with the first partner: with the target, with the cyber player.
    """
    other = "leader" if role == "follower" else "follower"
    roles = (other, role)
    target = cast.trainers[cast.target]
    seeds = draw_seeds([seed, 1], n_sessions)
    rows: list[dict[str, Any]] = []
    velocities: dict[str, list[np.ndarray]] = {target.label: [], "cyber player": [], "partners": []}
    n_samples = count_samples(SESSION_SECONDS, player.period)
    sessions: list[Session] = []
    for index in (*cast.seen, cast.unseen):
        partner = cast.trainers[index].player(other)
        for k, s in enumerate(seeds):
            for name, avatar in ((target.label, target.player(role)), ("cyber player", player)):
                session = play_compiled([partner, avatar], n_samples, s, roles=roles)
                trimmed = session.trimmed(TRIM)
                rows.append(
                    {"partner": cast.trainers[index].label, "player": name, "session": k}
                    | measure(trimmed)
                )
                velocities[name].append(trimmed.velocities[1])
                if name == target.label:
                    velocities["partners"].append(trimmed.velocities[0])
                if index == cast.seen[0] and k == 0:
                    sessions.append(session)
    return pd.DataFrame(rows), velocities, (sessions[0], sessions[1])


def measure(session: Session) -> dict[str, float]:
    """Return the table's CV, RMS (units) and EMD between the players' velocity IMS.

    Read from `mirror_avatar.metrics.session_metrics`; the CV is NaN when a player does not
    move at all (no phase).
    """
    metrics = session_metrics(session)
    return {
        "cv": metrics["phase_locking"],
        "rms": metrics["rmse"],
        "emd": metrics["emd_players"],
    }


def compare_baselines(
    player: AccelerationPlayer,
    cast: Cast,
    role: Role,
    n_sessions: int,
    seed: int,
    n_jobs: int = 2,
    scheduler: str | None = None,
) -> dict[str, float]:
    """RMS to the target (units) on held-out sessions: trained, untrained, copy the partner.

    The sessions are the target playing ``role`` with every partner, seen and unseen, seeded
    apart from training; the trained and untrained (seeded random policy) players replay each
    session open-loop in the target's place (`mirror_avatar.training.imitation.score_avatar`),
    and "copy the partner" is the RMS between the partner's and the target's positions.
    """
    generator = cast.trainers[cast.target].generator
    partners = [cast.trainers[i].generator for i in (*cast.seen, cast.unseen)]
    pairs = make_pairs(generator, partners, role)
    held_out = derive_seeds(seed + 1)[0]
    chunks = run_sessions(
        pairs,
        n_sessions,
        seed=held_out,
        scheduler=scheduler,
        n_jobs=n_jobs,
        progress=False,
    )
    sessions = list(itertools.chain.from_iterable(chunks))
    untrained = make_cyber_player(role, generator, agent=player.agent)
    untrained.initialise_policy(seed)
    copy = [np.sqrt(np.mean((s.positions[0, 1:] - s.positions[1, 1:]) ** 2)) for s in sessions]
    return {
        "trained": float(score_avatar(player, sessions)[1].mean()),
        "untrained (random Q)": float(score_avatar(untrained, sessions)[1].mean()),
        "copy the partner": float(np.mean(copy)),
    }


def make_table_one(result: RoleResult) -> pd.DataFrame:
    """Paper Table I: per partner, EMD to the partner and CV, RMS mean +- SD, target and cyber."""
    rows = {}
    for partner, block in result.records.groupby("partner", sort=False):
        row: dict[str, str] = {}
        for name in (result.target, "cyber player"):
            own = block[block["player"] == name]
            row[f"EMD {name}"] = f"{own['emd'].mean():.4f}"
            row[f"CV {name}"] = _mean_sd(own["cv"])
            row[f"RMS {name}"] = _mean_sd(own["rms"])
        rows[(result.role, _partner_name(str(partner), result))] = row
    return pd.DataFrame.from_dict(rows, orient="index")


def compute_emd_to_target(result: RoleResult) -> float:
    """EMD between the cyber player's and the target's velocity IMS, pooled over all sessions."""
    return compute_emd(
        compute_ims(np.concatenate(result.velocities["cyber player"])),
        compute_ims(np.concatenate(result.velocities[result.target])),
    )


def check_criteria(result: RoleResult) -> pd.DataFrame:
    """Per partner (the index): mean CV and RMS of the target and the cyber player, `CRITERIA`.

    Columns ``cv TARGET``, ``cv cyber``, ``rms TARGET``, ``rms cyber`` (means over the sessions,
    TARGET the target's label), ``emd to TARGET`` (the cyber player's pooled velocity IMS
    against the target's, same for every partner), then booleans ``cv within``, ``rms within``
    (difference at most ``max_difference``), ``cv >= min``, ``rms <= max``, ``emd <= max`` and
    ``all``.
    """
    emd = compute_emd_to_target(result)
    limit = CRITERIA["max_difference"]
    rows = {}
    for partner, block in result.records.groupby("partner", sort=False):
        target = block[block["player"] == result.target][["cv", "rms"]].mean()
        cyber = block[block["player"] == "cyber player"][["cv", "rms"]].mean()
        passed = {
            "cv within": abs(cyber["cv"] - target["cv"]) <= limit,
            "rms within": abs(cyber["rms"] - target["rms"]) <= limit,
            "cv >= min": cyber["cv"] >= CRITERIA["min_cv"],
            "rms <= max": cyber["rms"] <= CRITERIA["max_rms"],
            "emd <= max": emd <= CRITERIA["max_emd_to_target"],
        }
        row = {
            f"cv {result.target}": float(target["cv"]),
            "cv cyber": float(cyber["cv"]),
            f"rms {result.target}": float(target["rms"]),
            "rms cyber": float(cyber["rms"]),
            f"emd to {result.target}": emd,
        } | {key: bool(value) for key, value in passed.items()}
        row["all"] = all(passed.values())
        rows[_partner_name(str(partner), result)] = row
    return pd.DataFrame.from_dict(rows, orient="index")


def make_table_two(result: RoleResult) -> pd.DataFrame:
    """Paper Table II: paired t-tests of CV and RMS, target against cyber player, per partner.

    Sessions where either player has no CV (it did not move) are left out of the CV test.
    """
    rows = {}
    for partner, block in result.records.groupby("partner", sort=False):
        target = block[block["player"] == result.target].sort_values("session")
        cyber = block[block["player"] == "cyber player"].sort_values("session")
        row: dict[str, Any] = {}
        for key in ("cv", "rms"):
            a, b = target[key].to_numpy(), cyber[key].to_numpy()
            both = np.isfinite(a) & np.isfinite(b)
            if both.sum() < 2:
                row[f"{key.upper()} t(df)"], row[f"{key.upper()} p"] = "undefined", math.nan
                continue
            test = paired_ttest(a[both], b[both])
            row[f"{key.upper()} t(df)"] = f"t({test.df}) = {test.t:.2f}"
            row[f"{key.upper()} p"] = test.p
        rows[(result.role, _partner_name(str(partner), result))] = row
    return pd.DataFrame.from_dict(rows, orient="index")


def compute_regions(
    velocities: dict[str, list[np.ndarray]],
) -> tuple[dict[str, np.ndarray], dict[str, Any], pd.DataFrame]:
    """Similarity space of the sessions' velocity signatures and each group's 70% region.

    Returns the points per group (classical MDS of the EMD matrix), the ellipses and the table
    of pairwise overlaps (intersection / union).
    """
    names = list(velocities)
    ims = np.array([compute_ims(v) for name in names for v in velocities[name]])
    points = classical_mds(compute_emd_matrix(ims))
    counts = np.cumsum([0] + [len(velocities[name]) for name in names])
    groups = {name: points[counts[i] : counts[i + 1]] for i, name in enumerate(names)}
    ellipses = {
        name: confidence_ellipse(xy) if len(xy) >= 3 else None for name, xy in groups.items()
    }
    table = pd.DataFrame(np.nan, index=names, columns=names)
    for a in names:
        for b in names:
            ea, eb = ellipses[a], ellipses[b]
            if ea is not None and eb is not None:
                table.loc[a, b] = ellipse_overlap(ea, eb)
    return groups, ellipses, table


def _plot_example(result: RoleResult, partner: str) -> Any:
    with_target, with_cyber = result.example
    keep = with_target.times <= 20.0
    return plot_positions(
        with_target.times[keep],
        {
            f"partner {partner} (with {result.target})": with_target.positions[0, keep],
            result.target: with_target.positions[1, keep],
            "cyber player": with_cyber.positions[1, keep],
        },
        title=f"Cyber player as {result.role}",
    )


def _mean_sd(values: pd.Series) -> str:
    return f"{values.mean():.3f} +- {values.std(ddof=1):.3f}"


def _partner_name(label: str, result: RoleResult) -> str:
    return f"{label} (unseen)" if label == result.unseen else label


def _metrics(
    results: list[RoleResult],
    table_one: pd.DataFrame,
    table_two: pd.DataFrame,
    overlaps: pd.DataFrame,
    cast: Cast,
    seed: int,
    n_train: int,
    n_valid: int,
) -> dict[str, Any]:
    out: dict[str, Any] = {
        "seed": seed,
        "training_sessions": n_train,
        "validation_sessions_per_partner": n_valid,
        "trim_s": TRIM,
        "virtual_trainers": {t.label: list(t.trial_labels) for t in cast.trainers},
        "target": cast.trainers[cast.target].label,
        "paper_table_one": {k: list(v) for k, v in PAPER.items()},
    }
    for r in results:
        cyber = r.records[r.records["player"] == "cyber player"]
        p_values = table_two.loc[r.role, ["CV p", "RMS p"]].to_numpy(dtype=float)
        out[r.role] = {
            "training_seconds": r.train_seconds,
            "learning_curve": r.curve.as_rows(),
            "baselines_rms": r.baselines,
            "cyber_cv_mean": float(cyber["cv"].mean()),
            "cyber_rms_mean": float(cyber["rms"].mean()),
            "cyber_emd_to_partner_mean": float(cyber["emd"].mean()),
            "emd_cyber_to_target": compute_emd_to_target(r),
            "records": r.records.to_dict(orient="records"),
            "table_one": pd.DataFrame(table_one.loc[r.role]).to_dict(orient="index"),
            "table_two": pd.DataFrame(table_two.loc[r.role]).to_dict(orient="index"),
            "overlaps": overlaps.loc[r.role].to_dict(),
            "n_p_above_0.05": int((p_values > 0.05).sum()),
            "n_tests": int(p_values.size),
            "trained_beats_baselines": r.baselines["trained"]
            < min(r.baselines["untrained (random Q)"], r.baselines["copy the partner"]),
        }
    return out


def _describe(
    results: list[RoleResult],
    table_two: pd.DataFrame,
    cast: Cast,
    n_train: int,
    n_valid: int,
    agent: Agent,
) -> list[str]:
    target = cast.trainers[cast.target].label
    leader_input = (
        "The leader's state is [x - x_p, x' - r_s, x, r_s]"
        if agent == "tabular"
        else "The leader's input also holds r_s"
    )
    text = [
        f"Virtual trainers: {cast.describe()} For each role a {AGENT_NAMES[agent]} was trained "
        f"on {n_train} sessions of 60 s with the training partners (the paper: about 24 000), "
        f"then replaced {target} in {n_valid} closed-loop sessions per partner. Metrics leave "
        f"out the first {TRIM:g} s. {leader_input}, with r_s its own reference velocity drawn "
        f"from {target}'s IMS generator as {target} draws it (a departure from METHODS' [x, x', "
        "x_p, x_p']: a leader's motion comes from its own motion source, which the partner's "
        "state cannot predict).",
        f"Paper Table I: CV {PAPER['cv'][0]}-{PAPER['cv'][1]}, RMS {PAPER['rms'][0]}-"
        f"{PAPER['rms'][1]}, EMD {PAPER['emd'][0]}-{PAPER['emd'][1]}; Table II: all p > 0.05.",
    ]
    for r in results:
        cyber = r.records[r.records["player"] == "cyber player"]
        p = table_two.loc[r.role, ["CV p", "RMS p"]].to_numpy(dtype=float)
        b = r.baselines
        text.append(
            f"As {r.role}: trained in {r.train_seconds:.0f} s; the cyber player's CV "
            f"{cyber['cv'].mean():.3f}, RMS to the partner {cyber['rms'].mean():.3f}, EMD to the "
            f"partner {cyber['emd'].mean():.4f}; {int((p > 0.05).sum())} of {p.size} t-tests "
            f"with p > 0.05. RMS to {r.target} on held-out sessions: trained {b['trained']:.3f}, "
            f"untrained {b['untrained (random Q)']:.3f}, copy the partner "
            f"{b['copy the partner']:.3f} units"
            + (
                "."
                if b["trained"] < b["copy the partner"]
                else f" - copying the partner imitates {r.target} better than the trained player."
            )
        )
        text.append(_describe_criteria(r))
    if np.isnan(table_two[["CV p", "RMS p"]].to_numpy(dtype=float)).any():
        text.append("Some t-tests are undefined (a player that did not move, or no variance).")
    return text


def _describe_criteria(result: RoleResult) -> str:
    checks = check_criteria(result)
    target = result.target
    speeds = {
        name: float(np.abs(np.concatenate(result.velocities[name])).mean())
        for name in (target, "cyber player")
    }
    text = (
        f"Reproduction criteria (CV and RMS within {CRITERIA['max_difference']} of {target}'s, "
        f"CV >= {CRITERIA['min_cv']}, RMS <= {CRITERIA['max_rms']}, IMS within EMD "
        f"{CRITERIA['max_emd_to_target']} of {target}'s) met as {result.role} against "
        f"{int(checks['all'].sum())} of {len(checks)} partners; mean speed {target} "
        f"{speeds[target]:.3f}, cyber player {speeds['cyber player']:.3f} units/s."
    )
    below = checks[(checks[f"cv {target}"] < CRITERIA["min_cv"]) & checks["cv within"]].index
    if len(below):
        text += (
            f" Against {', '.join(below)} {target}'s own CV is below {CRITERIA['min_cv']}, so a "
            f"cyber player within {CRITERIA['max_difference']} of {target} cannot reach that "
            "bound: those partners' follower presets superimpose their own reference motion on "
            "the leader (METHODS section 5)."
        )
    return text
