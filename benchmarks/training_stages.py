"""Where a chunk of paper-scale training spends its CPU: generation and learning, stage by stage.

One chunk of ``mirror-avatar train`` (follower, target VT5, partners VT1..VT4, seed 0, 60 s
sessions, `mirror_avatar.engine.batch.run_chunk` as `mirror_avatar.training.imitation.imitate`
streams it) is generated and then learnt from, each stage timed on its own in this thread
(``time.thread_time``: CPU, so time the shared machine's other jobs take from this process is
not counted), the median of ``--repeats`` rounds. The stages:

- generation: the whole chunk (`run_chunk`); of it, the players' plans, references and packing
  (`mirror_avatar.engine.compiled.pack_session`), and the compiled loop (`run_plans` less
  the packing); the rest (plans, graphs, `Session` objects) is the chunk less `run_plans`;
- learning: a fresh cyber player's `QLearner.fit` over the chunk, made for the paper's run;
  of it, each session's `mirror_avatar.learning.training.ImitationTask`, exploration draws
  (`draw_exploration`), Q-learning kernel (`learn_session`) and target histogram
  (`count_velocities`); the rest is the learner's Python.

``python benchmarks/training_stages.py [--chunk 50] [--repeats 5]`` prints a Markdown table.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.engine.batch import run_chunk
from mirror_avatar.engine.compiled import pack_session, run_plans
from mirror_avatar.engine.loop import count_samples, spawn_session_seeds
from mirror_avatar.learning.kernels import draw_exploration, learn_session
from mirror_avatar.learning.training import ImitationTask, policy_arguments
from mirror_avatar.signatures.signature import count_velocities
from mirror_avatar.training.cast import SEEN_PARTNERS, TARGET, make_virtual_trainers
from mirror_avatar.training.imitation import (
    derive_seeds,
    make_cyber_player,
    make_learner,
    make_pairs,
)

DURATION = 60.0
PAPER_SESSIONS = 24_000
"""The learner is made for the paper's run (its learning curve's blocks are that run's)."""
TARGET_PLAYER = 1


def cpu_of(work: Callable[[], Any]) -> tuple[float, Any]:
    """Return the thread CPU (s) of one call of ``work``, and its result."""
    began = time.thread_time()
    result = work()
    return time.thread_time() - began, result


def measure(chunk: int, repeats: int) -> list[tuple[str, float]]:
    """Thread CPU (s) of each stage of one chunk of ``chunk`` sessions, in table order.

    Every stage is timed once in each of ``repeats`` rounds; a stage's figure is its median
    over the rounds, and a part found by difference is the median of the differences within
    each round.
    """
    trainers = make_virtual_trainers(load_zhai2017())
    target = trainers[TARGET].generator
    lineups = make_pairs(target, [trainers[i].generator for i in SEEN_PARTNERS], "follower")
    session_seed, learner_seed = derive_seeds(0)
    seeds = spawn_seeds(session_seed, chunk, bits=64)
    n_samples = count_samples(DURATION, lineups[0][0].period)
    run_chunk(lineups, seeds[:2], 0, n_samples)  # numba loads its cache before the clock
    plans, graph = chunk_plans(lineups, seeds, n_samples)
    rounds = []
    for _ in range(repeats):
        whole, sessions = cpu_of(lambda: run_chunk(lineups, seeds, 0, n_samples))
        packing, _ = cpu_of(lambda: pack_session(plans, graph, n_samples - 1))
        compiled, _ = cpu_of(lambda: run_plans(plans, graph, n_samples))
        generation = [whole, packing, compiled - packing, whole - compiled]
        rounds.append(generation + learning(sessions, target, learner_seed))
    names = [
        "generation: the chunk (`run_chunk`)",
        "  plans' references and packing (`pack_session`)",
        "  compiled loop (`run_plans` less packing)",
        "  plans, graphs, `Session` objects (the rest)",
        "learning: the chunk (`QLearner.fit`)",
        "  `ImitationTask.from_session`",
        "  exploration draws (`draw_exploration`)",
        "  Q-learning kernel (`learn_session`)",
        "  target histogram (`count_velocities`)",
        "  the learner's Python (the rest)",
    ]
    return list(zip(names, np.median(rounds, axis=0).tolist(), strict=True))


def chunk_plans(
    lineups: list[Any], seeds: np.ndarray, n_samples: int
) -> tuple[list[Any], np.ndarray]:
    """Return the chunk's player plans and block-diagonal graph, as `run_chunk` makes them."""
    plans: list[Any] = []
    for i, seed in enumerate(seeds):
        players = lineups[i % len(lineups)]
        player_seeds, _ = spawn_session_seeds(int(seed), len(players))
        plans += [p.plan(s, n_samples - 1) for p, s in zip(players, player_seeds, strict=True)]
    pair = np.ones((2, 2), dtype=np.int8) - np.eye(2, dtype=np.int8)
    return plans, np.kron(np.eye(len(seeds), dtype=np.int8), pair)


def learning(sessions: list[Any], target: Any, seed: int) -> list[float]:
    """Thread CPU (s) of the learner over ``sessions`` and of its parts, in table order.

    A fresh cyber player learns from the sessions; its parts are then timed on its Q-table.
    """
    player = make_cyber_player("follower", target)
    whole, _ = cpu_of(
        lambda: make_learner(player, PAPER_SESSIONS, seed, progress=False).fit(sessions)
    )
    policy = policy_arguments(player)
    period = player.period
    tasks_cpu, tasks = cpu_of(
        lambda: [ImitationTask.from_session(s, TARGET_PLAYER, period) for s in sessions]
    )
    rng = np.random.default_rng(seed)
    n_actions = policy.actions.size
    draws_cpu, draws = cpu_of(
        lambda: [draw_exploration(rng, t.target_x.size - 1, n_actions) for t in tasks]
    )

    def kernel() -> None:
        for task, (uniform, actions) in zip(tasks, draws, strict=True):
            learn_session(
                policy.q_table, task.partner_x, task.partner_v, task.target_x, task.target_v,
                task.target_r, policy.mode, policy.edges, policy.offsets, policy.actions,
                policy.record, policy.n_substeps, 0.1, 0.95, 0.1, uniform, actions,
            )  # fmt: skip

    kernel_cpu, _ = cpu_of(kernel)
    counts_cpu, _ = cpu_of(
        lambda: [count_velocities(s.velocities[TARGET_PLAYER]) for s in sessions]
    )
    rest = whole - tasks_cpu - draws_cpu - kernel_cpu - counts_cpu
    return [whole, tasks_cpu, draws_cpu, kernel_cpu, counts_cpu, rest]


def table(stages: list[tuple[str, float]], chunk: int) -> str:
    """Make a Markdown table: CPU per chunk and per session of each stage, and its share."""
    total = sum(cpu for name, cpu in stages if not name.startswith(" "))
    lines = [
        "| stage | CPU per chunk (ms) | per session (ms) | share of generation + learning |",
        "|---|---|---|---|",
    ]
    for name, cpu in stages:
        lines.append(
            f"| {name} | {1e3 * cpu:.1f} | {1e3 * cpu / chunk:.2f} | {100 * cpu / total:.0f} % |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--chunk", type=int, default=50, help="sessions per chunk")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    print(table(measure(args.chunk, args.repeats), args.chunk))


if __name__ == "__main__":
    main()
