"""A cyber player in a group on random graphs (METHODS section 8).

Virtual trainers improvise together with the `mirror_avatar.dynamics.GROUP` parameters, each with
the signature of one of the cyber-player experiment's virtual "persons" (`choose_members`: with
the bundled data VT1 from the fast trials, VT4, VT6 and VT5 from the slow ones, a group of four;
the target, VT5, is the last player). A tabular cyber player is trained to take the target's
place on sessions with a new random connected graph each
(`mirror_avatar.training.imitation.train_group_cyber_player`), then plays closed-loop in its
place on new random graphs, each session paired with the same session played by the target (same
seed: same graph, same partners' references). Reported in the layout of the group's published
example: the target's CV, RMS, time lag and maximum cross-correlation against the mean of its
neighbours, and the group synchronisation, each mean ± SD, with paired t-tests; the same on fixed
topologies; baselines on held-out sessions; figures of positions, rho_g(t), the graph and each
player's rho_k on a complete graph and on a path.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from mirror_avatar.common.seeds import draw_seeds
from mirror_avatar.engine.batch import play_compiled
from mirror_avatar.engine.loop import count_samples
from mirror_avatar.figures.graphs import plot_graph
from mirror_avatar.figures.learning import plot_bars, plot_learning_curves
from mirror_avatar.figures.sessions import plot_group_synchronisation, plot_series
from mirror_avatar.files.trials import Trial
from mirror_avatar.learning.acceleration_player import AccelerationPlayer
from mirror_avatar.metrics import (
    TRIM,
    compute_cluster_phase,
    compute_phase,
    paired_ttest,
    session_metrics,
)
from mirror_avatar.players import Player
from mirror_avatar.report import Section
from mirror_avatar.sessions.graphs import GraphSource, make_graph, random_connected_graph
from mirror_avatar.sessions.session import Session
from mirror_avatar.training.agents import AGENT_NAMES
from mirror_avatar.training.cast import Cast, VirtualTrainerSpec, cast_virtual_trainers
from mirror_avatar.training.imitation import (
    Agent,
    derive_seeds,
    make_group,
    make_group_cyber_player,
    score_avatar,
    train_group_cyber_player,
)

CYBER = "cyber player"
"""The cyber player's name in the records (the target's is its label)."""

TRAINING_SESSIONS: dict[Agent, int] = {"tabular": 4000, "dqn": 300}
"""Training sessions by default, per agent (**choice**, as the dyad's
`mirror_avatar.experiments.cyber_player.TRAINING_SESSIONS`)."""
QUICK_TRAINING_SESSIONS: dict[Agent, int] = {"tabular": 300, "dqn": 40}
VALIDATION_SESSIONS = 60
"""Sessions of the validation on random graphs (the published example's 60)."""

QUICK_VALIDATION_SESSIONS = 6
TOPOLOGY_SESSIONS = 20
QUICK_TOPOLOGY_SESSIONS = 3
BASELINE_SESSIONS = 60
QUICK_BASELINE_SESSIONS = 10
DURATION = 60.0

TOPOLOGIES = ("complete", "ring", "path", "star")

MEASURES = ("phase_locking", "group_synchronisation", "rmse", "time_lag",
            "max_cross_correlation")  # fmt: skip
"""What is compared, in the published table's order."""

PUBLISHED = {
    "phase_locking": ((0.818, 0.092), (0.803, 0.053)),
    "group_synchronisation": ((0.850, 0.051), (0.843, 0.046)),
    "rmse": ((0.063, 0.023), (0.054, 0.006)),
    "time_lag": ((-0.021, None), (-0.035, None)),
    "max_cross_correlation": ((0.873, None), (0.886, None)),
}
"""The group's published example (METHODS section 8): (mean, SD) of the DQN cyber player, then of
the virtual trainer it imitates."""

CRITERIA = {"max_difference": 0.03, "max_rms_sd_ratio": 1.5}
"""The cyber player's mean CV, group synchronisation and RMS each within ``max_difference`` of
the target's, and its RMS SD at most ``max_rms_sd_ratio`` times the target's."""


def run(
    trials: Sequence[Trial],
    quick: bool = False,
    seed: int = 0,
    n_sessions: int | None = None,
    n_jobs: int = 2,
    agent: Agent = "tabular",
    scheduler: str | None = None,
) -> Section:
    """Train a cyber player in a group and validate it against the target VT.

    Parameters
    ----------
    trials
        Solo trials; the virtual trainers are made from them (`cast_virtual_trainers`) and the
        group chosen among them (`choose_members`).
    quick
        Fewer training, validation and topology sessions.
    seed
        Seeds the generators, the training run, the validation and the baselines.
    n_sessions
        Override the number of training sessions.
    n_jobs
        Local threads generating training sessions.
    agent
        ``"tabular"`` (a Q-table) or ``"dqn"`` (a deep Q-network with dynamic input).
    scheduler
        Address of a Dask scheduler (``tcp://host:port``) whose workers play the training
        sessions instead of local threads (the same sessions either way).
    """
    n_train = n_sessions or (QUICK_TRAINING_SESSIONS if quick else TRAINING_SESSIONS)[agent]
    n_valid = QUICK_VALIDATION_SESSIONS if quick else VALIDATION_SESSIONS
    n_topology = QUICK_TOPOLOGY_SESSIONS if quick else TOPOLOGY_SESSIONS
    n_base = QUICK_BASELINE_SESSIONS if quick else BASELINE_SESSIONS
    cast = cast_virtual_trainers(trials, seed=seed)
    members = [cast.trainers[i] for i in choose_members(cast)]
    *partners, target = [m.generator for m in members]
    start = time.perf_counter()
    player, curve = train_group_cyber_player(
        target,
        partners,
        n_sessions=n_train,
        seed=seed,
        scheduler=scheduler,
        n_jobs=n_jobs,
        agent=agent,
    )
    train_seconds = time.perf_counter() - start
    group = make_group(target, partners)
    seeds = draw_seeds([seed, 2], n_valid + n_topology)
    label = members[-1].label
    records, examples = compare(group, label, player, seeds[:n_valid], random_connected_graph)
    table = summarise(records)
    topology_records = pd.concat(
        {name: compare(group, label, player, seeds[n_valid:], make_graph(name, len(group)))[0]
         for name in TOPOLOGIES}
    )  # fmt: skip
    baselines = compare_baselines(player, group, n_base, seed)
    synchrony = per_player_synchronisation(group, seeds[0])
    checks = check_criteria(records)
    metrics = {
        "seed": seed,
        "agent": agent,
        "training_sessions": n_train,
        "training_seconds": train_seconds,
        "validation_sessions": n_valid,
        "topology_sessions": n_topology,
        "trim_s": TRIM,
        "members": {f"player {i}": m.label for i, m in enumerate(members)},
        "member_trials": {m.label: list(m.trial_labels) for m in members},
        "target": label,
        "table": table.to_dict(orient="index"),
        "criteria": checks,
        "topologies": topology_table(topology_records).to_dict(orient="index"),
        "per_player_synchronisation": synchrony,
        "baselines_rms": baselines,
        "learning_curve": curve.as_rows(),
        "records": records.to_dict(orient="records"),
        "published": {k: {"cyber": v[0], "virtual trainer": v[1]} for k, v in PUBLISHED.items()},
    }
    labels = [m.label for m in members[:-1]] + [f"{label} (target)"]
    return Section(
        key="group",
        title=f"Groups: a cyber player in a group of {len(group)} on random graphs (METHODS "
        "section 8)",
        text=_describe(members, table, checks, baselines, synchrony, n_train, n_valid, agent),
        tables={
            f"Target {label} and the cyber player in its place, random graphs (mean +- SD; CV, "
            "RMS, lag and cross-correlation against the mean of the target's neighbours)": table,
            "Fixed topologies (means)": topology_table(topology_records),
            f"RMS to {label} on held-out group sessions (units)": pd.DataFrame(
                baselines, index=["RMS"]
            ),
            "Each player's synchronisation to the group (rho_k), virtual trainers only": (
                pd.DataFrame(synchrony)
            ),
        },
        figures=_figures(examples, labels, curve, baselines, synchrony),
        metrics=metrics,
    )


def choose_members(cast: Cast) -> tuple[int, ...]:
    """Pick the group from the cast (**choice**): indices into ``cast.trainers``.

    The first and the last training partners, the unseen partner, then the target, each once:
    four for the bundled data and for four people or more, three for three people.
    """
    first, last = cast.seen[0], cast.seen[-1]
    return tuple(dict.fromkeys((first, last, cast.unseen, cast.target)))


def compare(
    group: Sequence[Player],
    label: str,
    player: AccelerationPlayer,
    seeds: Sequence[int],
    graph: GraphSource,
) -> tuple[pd.DataFrame, tuple[Session, Session]]:
    """Play each seed with the target VT (the last of ``group``) and the cyber player in its place.

    Returns
    -------
    records : DataFrame
        One row per session and player (``label``, the target's, or `CYBER`): the target's
        ``phase_locking``, ``rmse``, ``time_lag`` and ``max_cross_correlation`` against its
        neighbours' mean, and the ``group_synchronisation``.
    examples : tuple of Session
        The first session with the target and with the cyber player.
    """
    with_cyber = [*group[:-1], player]
    rows, examples = [], []
    n_samples = count_samples(DURATION, player.period)
    for k, seed in enumerate(seeds):
        for name, lineup in ((label, group), (CYBER, with_cyber)):
            session = play_compiled(lineup, n_samples, seed, graph)
            rows.append({"session": k, "player": name} | measure(session))
            if k == 0:
                examples.append(session)
    return pd.DataFrame(rows), (examples[0], examples[1])


def measure(session: Session) -> dict[str, float]:
    """Return the target's (last player's) coordination with its neighbours and group synchrony."""
    metrics = session_metrics(session, TRIM)
    target = metrics["players"][-1]
    return {key: float(target[key]) for key in MEASURES if key in target} | {
        "group_synchronisation": metrics["group_synchronisation"]
    }


def summarise(records: pd.DataFrame) -> pd.DataFrame:
    """Tabulate per measure the mean +- SD of the target and the cyber player, and a paired t-test.

    The target's columns are named by its label (the records' other player).
    """
    vt, cyber = _split_players(records)
    label = vt["player"].iloc[0]
    rows = {}
    for key in MEASURES:
        test = paired_ttest(vt[key].to_numpy(), cyber[key].to_numpy())
        published_cyber, published_vt = PUBLISHED[key]
        rows[key] = {
            f"{label} mean": vt[key].mean(),
            f"{label} SD": vt[key].std(ddof=1),
            "cyber mean": cyber[key].mean(),
            "cyber SD": cyber[key].std(ddof=1),
            "t(df)": f"t({test.df}) = {test.t:.2f}",
            "p": test.p,
            "published VT": _published(published_vt),
            "published cyber (DQN)": _published(published_cyber),
        }
    return pd.DataFrame.from_dict(rows, orient="index")


def _split_players(records: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Split the records into the target's and the cyber player's, each in session order."""
    is_cyber = records["player"] == CYBER
    return records[~is_cyber].sort_values("session"), records[is_cyber].sort_values("session")


def _published(value: tuple[float, float | None]) -> str:
    mean, sd = value
    return f"{mean:.3f}" if sd is None else f"{mean:.3f} +- {sd:.3f}"


def check_criteria(records: pd.DataFrame) -> dict[str, Any]:
    """`CRITERIA` on the random-graph sessions: differences of the means and the RMS SD ratio."""
    vt, cyber = _split_players(records)
    out: dict[str, Any] = {}
    for key in ("phase_locking", "group_synchronisation", "rmse"):
        difference = float(cyber[key].mean() - vt[key].mean())
        out[f"{key} difference"] = difference
        out[f"{key} within"] = abs(difference) <= CRITERIA["max_difference"]
    ratio = float(cyber["rmse"].std(ddof=1) / vt["rmse"].std(ddof=1))
    out["rmse SD ratio"] = ratio
    out["rmse SD within"] = ratio <= CRITERIA["max_rms_sd_ratio"]
    out["all"] = all(v for k, v in out.items() if k.endswith("within"))
    return out


def topology_table(records: pd.DataFrame) -> pd.DataFrame:
    """Means of CV, group synchronisation and RMS per topology (rows), target and cyber player."""
    frame = records.reset_index(level=0).rename(columns={"level_0": "topology"})
    means = frame.pivot_table(
        index="topology",
        columns="player",
        values=["phase_locking", "group_synchronisation", "rmse"],
        aggfunc="mean",
        sort=False,
    )
    means.columns = [" ".join(map(str, column)) for column in means.columns]
    return means


def compare_baselines(
    player: AccelerationPlayer, group: Sequence[Player], n_sessions: int, seed: int
) -> dict[str, float]:
    """RMS to the target (units) on held-out group sessions: trained, untrained, copy neighbours.

    The sessions are the virtual-trainer group on new random graphs; the players replay each
    open-loop in the target's place (the last player, `score_avatar`); "copy the neighbours"
    is the RMS between the mean position of the target's neighbours and the target's.
    """
    target = len(group) - 1
    held_out = derive_seeds(seed + 1)[0]
    n_samples = count_samples(DURATION, player.period)
    sessions = [
        play_compiled(group, n_samples, s, random_connected_graph)
        for s in draw_seeds(held_out, n_sessions)
    ]
    untrained = make_group_cyber_player(player.reference, agent=player.agent, n_players=len(group))
    untrained.initialise_policy(seed)
    copies = []
    for session in sessions:
        neighbours = np.flatnonzero(session.graph[target])
        mean = session.positions[neighbours, 1:].mean(axis=0)
        copies.append(np.sqrt(np.mean((mean - session.positions[target, 1:]) ** 2)))
    return {
        "trained": float(score_avatar(player, sessions, target)[1].mean()),
        "untrained (random Q)": float(score_avatar(untrained, sessions, target)[1].mean()),
        "copy the neighbours' mean": float(np.mean(copies)),
    }


def per_player_synchronisation(group: Sequence[Player], seed: int) -> dict[str, dict[str, float]]:
    """Each player's rho_k in one session of the VT group on a complete graph and on a path."""
    n_samples = count_samples(DURATION, group[0].period)
    out = {}
    for name in ("complete", "path"):
        session = play_compiled(group, n_samples, seed, make_graph(name, len(group)))
        x = session.trimmed(TRIM).positions
        cluster = compute_cluster_phase(np.array([compute_phase(row) for row in x]))
        out[name] = {f"player {i}": float(r) for i, r in enumerate(cluster.individual)}
        out[name]["group (mean rho_g)"] = float(cluster.group.mean())
    return out


def _figures(
    examples: tuple[Session, Session],
    labels: list[str],
    curve: Any,
    baselines: dict[str, float],
    synchrony: dict[str, dict[str, float]],
) -> dict[str, Any]:
    with_vt, with_cyber = (s.trimmed(TRIM) for s in examples)
    keep = with_vt.times <= 20.0
    positions = {label: x[keep] for label, x in zip(labels, with_vt.positions, strict=True)}
    target = labels[-1].removesuffix(" (target)")
    positions[f"cyber player (in {target}'s place)"] = with_cyber.positions[-1, keep]
    rho = {}
    for name, session in ((f"with {target}", with_vt), ("with the cyber player", with_cyber)):
        phases = np.array([compute_phase(x) for x in session.positions])
        rho[name] = compute_cluster_phase(phases).group
    bars = {name: {k: v for k, v in values.items() if k.startswith("player")}
            for name, values in synchrony.items()}  # fmt: skip
    return {
        "Positions of the players, first random-graph session (first 20 s)": plot_series(
            with_vt.times[keep], positions, "position (units)", f"A group of {len(labels)}"
        ),
        "Group synchronisation rho_g(t) in that session": plot_group_synchronisation(
            with_vt.times, rho
        ),
        "That session's graph (drawn from its seed)": plot_graph(with_vt.graph, labels),
        "Each player's synchronisation to the group, complete graph and path": plot_bars(
            bars,
            "rho_k",
            f"Synchronisation to the group (path: players 0 and {len(labels) - 1} are the ends)",
        ),
        "Learning curve (dashed: baselines on held-out sessions)": plot_learning_curves(
            {"trained cyber player": (curve.sessions, curve.rms)},
            baselines,
            title=f"Learning to imitate {target} in a group",
        ),  # fmt: skip
    }


def _describe(
    members: Sequence[VirtualTrainerSpec],
    table: pd.DataFrame,
    checks: dict[str, Any],
    baselines: dict[str, float],
    synchrony: dict[str, dict[str, float]],
    n_train: int,
    n_valid: int,
    agent: Agent,
) -> list[str]:
    who = ", ".join(f"{m.label} ({', '.join(m.trial_labels)})" for m in members)
    path, complete = synchrony["path"], synchrony["complete"]["group (mean rho_g)"]
    copy = baselines["copy the neighbours' mean"]
    ends = f"{path['player 0']:.3f} and {path[f'player {len(members) - 1}']:.3f}"
    middle = " and ".join(f"{path[f'player {i}']:.3f}" for i in range(1, len(members) - 1))
    return [
        f"{len(members)} virtual trainers improvise together with the group parameters of "
        f"METHODS section 8 (theta_p 0.85, theta_s 0.1, theta_v 0.05, omega 0.75): {who}; "
        f"the last is the target. A {AGENT_NAMES[agent]} was trained on {n_train} sessions of "
        f"{DURATION:g} s in the target's place, each on a new random connected graph, then "
        f"replaced it in {n_valid} sessions on new random graphs, each paired with the same "
        f"session (same seed and graph) played by the target. The first {TRIM:g} s are left "
        "out. CV, RMS, time lag and cross-correlation are the target's against the mean of its "
        "neighbours.",
        f"Criteria: mean CV, group synchronisation and RMS within {CRITERIA['max_difference']} "
        f"of the target's, RMS SD at most {CRITERIA['max_rms_sd_ratio']} x the target's: "
        + ("all met" if checks["all"] else "not all met")
        + f" (differences CV {checks['phase_locking difference']:+.3f}, group "
        f"synchronisation {checks['group_synchronisation difference']:+.3f}, RMS "
        f"{checks['rmse difference']:+.3f}; RMS SD ratio {checks['rmse SD ratio']:.2f}; the "
        "published DQN's was 3.8).",
        f"RMS to the target on held-out sessions: trained {baselines['trained']:.3f}, untrained "
        f"{baselines['untrained (random Q)']:.3f}, copying the neighbours' mean "
        f"{copy:.3f} units.",
        f"Virtual trainers alone: group synchronisation {complete:.3f} on a complete graph; "
        f"on a path the ends synchronise to the group with rho_k {ends}, the middle with "
        f"{middle}.",
    ]
