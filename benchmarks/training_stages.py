"""Where a chunk of paper-scale training spends its CPU: generation and learning, stage by stage.

One chunk of ``mirror-avatar train`` (follower, target VT5, partners VT1..VT4, seed 0, 60 s
sessions, `mirror_avatar.engine.batch.run_chunk` as `mirror_avatar.training.imitation.imitate`
streams it) is generated and then learnt from, each stage timed on its own in this thread
(``time.thread_time``: CPU, so time the shared machine's other jobs take from this process is
not counted), the least of ``--repeats`` repetitions. The stages:

- generation: the whole chunk (`run_chunk`); of it, the players' plans, references and packing
  (`mirror_avatar.engine.compiled.pack_session`), and the compiled loop (`run_plans` less
  the packing); the rest (plans, graphs, `Session` objects) is the chunk less `run_plans`;
- learning: each session's `mirror_avatar.learning.training.ImitationTask`, exploration draws
  (`draw_exploration`), Q-learning kernel (`learn_session`) and target histogram
  (`count_velocities`), and the learner's whole step (`QLearner.partial_fit` over the chunk).

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


def least_cpu(work: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    """Return the least thread CPU (s) of ``repeats`` calls of ``work``, and its last result."""
    best, result = np.inf, None
    for _ in range(repeats):
        began = time.thread_time()
        result = work()
        best = min(best, time.thread_time() - began)
    return best, result


def measure(chunk: int, repeats: int) -> list[tuple[str, float]]:
    """Thread CPU (s) of each stage of one chunk of ``chunk`` sessions, in table order."""
    trainers = make_virtual_trainers(load_zhai2017())
    target = trainers[TARGET].generator
    lineups = make_pairs(target, [trainers[i].generator for i in SEEN_PARTNERS], "follower")
    session_seed, learner_seed = derive_seeds(0)
    seeds = spawn_seeds(session_seed, chunk, bits=64)
    n_samples = count_samples(DURATION, lineups[0][0].period)
    run_chunk(lineups, seeds[:2], 0, n_samples)  # numba loads its cache before the clock
    whole, sessions = least_cpu(lambda: run_chunk(lineups, seeds, 0, n_samples), repeats)
    plans, graph = chunk_plans(lineups, seeds, n_samples)
    packing, _ = least_cpu(lambda: pack_session(plans, graph, n_samples - 1), repeats)
    compiled, _ = least_cpu(lambda: run_plans(plans, graph, n_samples), repeats)
    stages = [
        ("generation: the chunk (`run_chunk`)", whole),
        ("  plans' references and packing (`pack_session`)", packing),
        ("  compiled loop (`run_plans` less packing)", compiled - packing),
        ("  plans, graphs, `Session` objects (the rest)", whole - compiled),
    ]
    return stages + learning(sessions, target, learner_seed, repeats)


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


def learning(sessions: list[Any], target: Any, seed: int, repeats: int) -> list[tuple[str, float]]:
    """Thread CPU (s) of the learner's stages over ``sessions``, in table order."""
    player = make_cyber_player("follower", target)
    learner = make_learner(player, PAPER_SESSIONS, seed, progress=False)
    whole, _ = least_cpu(lambda: learner.fit(sessions), repeats)
    policy = policy_arguments(player)
    period = player.period
    tasks_cpu, tasks = least_cpu(
        lambda: [ImitationTask.from_session(s, TARGET_PLAYER, period) for s in sessions], repeats
    )
    rng = np.random.default_rng(seed)
    n_actions = policy.actions.size
    draws_cpu, draws = least_cpu(
        lambda: [draw_exploration(rng, t.target_x.size - 1, n_actions) for t in tasks], repeats
    )

    def kernel() -> None:
        for task, (uniform, actions) in zip(tasks, draws, strict=True):
            learn_session(
                policy.q_table, task.partner_x, task.partner_v, task.target_x, task.target_v,
                task.target_r, policy.mode, policy.edges, policy.offsets, policy.actions,
                policy.record, policy.n_substeps, 0.1, 0.95, 0.1, uniform, actions,
            )  # fmt: skip

    kernel_cpu, _ = least_cpu(kernel, repeats)
    counts_cpu, _ = least_cpu(
        lambda: [count_velocities(s.velocities[TARGET_PLAYER]) for s in sessions], repeats
    )
    return [
        ("learning: the chunk (`QLearner.fit`)", whole),
        ("  `ImitationTask.from_session`", tasks_cpu),
        ("  exploration draws (`draw_exploration`)", draws_cpu),
        ("  Q-learning kernel (`learn_session`)", kernel_cpu),
        ("  target histogram (`count_velocities`)", counts_cpu),
        (
            "  the learner's Python (the rest)",
            whole - tasks_cpu - draws_cpu - kernel_cpu - counts_cpu,
        ),
    ]


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
