"""Deep cyber player (DQN) beside the tabular one: validation, training time, decision time.

For each of the paper's Table I roles (follower, leader) and for the group of METHODS section 8,
both agents are trained on the same virtual-trainer sessions and validated against the target
VT5 in closed loop (`mirror_avatar.experiments.cyber_player.run_role`,
`mirror_avatar.experiments.group.run`); the rows give, per partner, the target's, the tabular
player's and the deep player's mean CV and RMS, and whether each is within the criterion of
the target (0.05 for dyads, 0.03 for groups). Training times are wall-clock on this machine
(2 threads generate sessions while the main one learns). Decision time is one greedy step of each
player's compiled kernel, called from Python, and of its Python ``step``.
"""

from __future__ import annotations

import time
import timeit

import numpy as np

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.deep.player import DeepCyberPlayer, deep_step
from mirror_avatar.deep.training import DQNLearner
from mirror_avatar.experiments import cyber_player, group
from mirror_avatar.learning.agent import CyberPlayer, cyber_step
from mirror_avatar.players import Observation
from mirror_avatar.testing import make_follower_sessions
from mirror_avatar.training.agents import AGENTS
from mirror_avatar.training.cast import cast_virtual_trainers
from mirror_avatar.training.imitation import (
    TRAINING_ROLES,
    make_cyber_player,
    make_group_cyber_player,
)


def run(quick: bool) -> list[dict]:
    trials = load_zhai2017()
    rows = decision_rows() + update_rows(trials)
    rows += dyad_rows(trials, quick)
    rows += group_rows(trials, quick)
    return rows


def decision_rows() -> list[dict]:
    """One greedy decision of each player (dyad follower, group member of four)."""
    seen = Observation(0, np.array([0.1, -0.2, 0.3]), np.array([0.2, 0.0, -0.1]), np.zeros(3))
    rows = []
    reference = load_zhai2017()[0]
    for name, player in (
        ("tabular follower", make_cyber_player("follower")),
        ("deep follower (own reference)", make_cyber_player("follower", reference, agent="dqn")),
        ("deep group member (3 slots, own reference)", make_group_cyber_player(
            reference, agent="dqn")),
    ):  # fmt: skip
        player.initialise_policy(0)
        player.reset(seed=0)
        kernel = _kernel_call(player, seen)
        kernel()
        n = 20_000
        kernel_us = timeit.timeit(kernel, number=n) / n * 1e6
        step_us = timeit.timeit(lambda p=player: p.step(seen), number=n) / n * 1e6
        rows.append({"name": f"decision, {name}: compiled kernel", "value": kernel_us,
                     "unit": "µs", "note": f"Python step() {step_us:.1f} µs"})  # fmt: skip
    return rows


def _kernel_call(player, seen: Observation):  # noqa: ANN202 - a closure
    record = player.params.record()[0]
    policy = player.policy_
    if isinstance(player, DeepCyberPlayer):
        return lambda: deep_step(
            policy.weights, policy.sizes, policy.n_slots, policy.use_reference, policy.actions,
            record, policy.n_substeps, 0.0, 0.1, seen.positions, seen.velocities, 0.2,
        )  # fmt: skip
    assert isinstance(player, CyberPlayer)
    disc = policy.discretisation
    return lambda: cyber_step(
        policy.q_table, disc.mode, disc.flat_edges, disc.offsets, policy.actions, record,
        policy.n_substeps, 0.0, 0.1, seen.positions, seen.velocities, 0.2,
    )  # fmt: skip


def update_rows(trials) -> list[dict]:
    """DQN updates per second on real follower sessions (one per step, minibatch 32).

    The sessions are recordings (no reference velocity), so the player sees its own and its
    partner's state only.
    """
    sessions = make_follower_sessions([t for t in trials if t.group == "slow"])
    player = DeepCyberPlayer(actions=make_cyber_player("follower").actions)
    DQNLearner(DeepCyberPlayer(), progress=False).fit(sessions[:1])
    learner = DQNLearner(player, random_state=0, progress=False)
    start = time.perf_counter()
    learner.fit(sessions)
    seconds = time.perf_counter() - start
    updates = int(learner.replay_.counters[1])
    steps = int(learner.replay_.counters[0])
    note = f"{steps} steps, {updates} updates, {len(sessions)} real sessions"
    return [{"name": "DQN learning step (act, store, one minibatch update), 100-50-50",
             "value": seconds / steps * 1e6, "unit": "µs", "note": note}]  # fmt: skip


def dyad_rows(trials, quick: bool) -> list[dict]:
    """Table I per role: target, tabular and deep player against each partner."""
    cast = cast_virtual_trainers(trials)
    n_valid = 4 if quick else cyber_player.VALIDATION_SESSIONS
    n_base = 10
    rows = []
    for role in TRAINING_ROLES:
        results = {}
        for agent in AGENTS:
            n_train = 30 if quick else cyber_player.TRAINING_SESSIONS[agent]
            results[agent] = cyber_player.run_role(
                cast, role, n_train, n_valid, n_base, 0, 2, agent
            )
            seconds = results[agent].train_seconds
            rows.append({"name": f"training, {role}, {agent}", "value": seconds,
                         "unit": "s", "note": f"{n_train} sessions of 60 s"})  # fmt: skip
        rows += _table_one_rows(role, results)
    return rows


def _table_one_rows(role: str, results: dict) -> list[dict]:
    limit = cyber_player.CRITERIA["max_difference"]
    checks = {agent: cyber_player.check_criteria(result) for agent, result in results.items()}
    target = results["tabular"].target
    rows = []
    for partner in checks["tabular"].index:
        tabular, deep = checks["tabular"].loc[partner], checks["dqn"].loc[partner]
        for measure in ("cv", "rms"):
            mine, theirs = deep[f"{measure} cyber"], deep[f"{measure} {target}"]
            verdict = "within" if deep[f"{measure} within"] else "NOT within"
            rows.append({
                "name": f"{role} with {partner}: {measure.upper()}",
                "value": float(mine),
                "baseline": float(theirs),
                "note": f"deep - {target} {mine - theirs:+.3f} ({verdict} {limit}); tabular "
                f"{tabular[f'{measure} cyber']:.3f}",
            })  # fmt: skip
    return rows


def group_rows(trials, quick: bool) -> list[dict]:
    """Run the group experiment for each agent: CV, group synchronisation, RMS against VT5's."""
    rows = []
    for agent in AGENTS:
        section = group.run(trials, quick=quick, n_sessions=30 if quick else None, agent=agent)
        metrics = section.metrics
        rows.append({"name": f"training, group of 4, {agent}", "value": metrics["training_seconds"],
                     "unit": "s", "note": f"{metrics['training_sessions']} sessions of 60 s, "
                     "a new random graph each"})  # fmt: skip
        criteria = metrics["criteria"]
        for measure in ("phase_locking", "group_synchronisation", "rmse"):
            line = metrics["table"][measure]
            target = next(k for k in line if k.endswith(" mean") and not k.startswith("cyber"))
            within = criteria[f"{measure} within"]
            rows.append({
                "name": f"group, {agent}: {measure}",
                "value": line["cyber mean"],
                "baseline": line[target],
                "note": f"SD {line['cyber SD']:.3f} vs {line[target.replace('mean', 'SD')]:.3f}; "
                f"difference {criteria[f'{measure} difference']:+.4f} "
                f"({'within' if within else 'NOT within'} {group.CRITERIA['max_difference']})",
            })  # fmt: skip
        bound = "at most 1.5" if criteria["rmse SD within"] else "ABOVE 1.5"
        rows.append({"name": f"group, {agent}: RMS SD ratio to the target's",
                     "value": criteria["rmse SD ratio"], "note": bound})  # fmt: skip
    return rows
