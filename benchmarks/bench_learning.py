"""Cyber player: Q-learning speed, policy latency, memory and learning quality.

Compiled Q-learning against a plain Python loop, policy decision time, peak memory, and how well
the player learns a real-data follower task with relative and absolute state features.

Sessions: partner = a bundled slow real trial resampled to 1/T (60 s, about 2000 steps), target =
the same trial 0.3 s later (a follower). The pure-Python baseline runs the same Q-learning on a
subset of steps in the same run.
"""

from __future__ import annotations

import math
import resource
import time
import timeit
import tracemalloc
from collections.abc import Iterator

import numpy as np

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.learning import (
    DEFAULT_ACTIONS,
    CyberPlayer,
    QLearner,
    make_default_discretisation,
    make_follower_sessions,
)
from mirror_avatar.players import CONTROL_PERIOD


def follower_sessions(group: str = "slow") -> tuple[np.ndarray, np.ndarray]:
    """Sessions (k, 2, n) from the bundled trials of one style: partner and its 0.3 s late copy."""
    return make_follower_sessions([t for t in load_zhai2017() if t.group == group], lag=0.3)


def cycle(chunk: tuple[np.ndarray, np.ndarray], n_sessions: int) -> Iterator[tuple]:
    positions, velocities = chunk
    for i in range(n_sessions):
        yield positions[i % len(positions)], velocities[i % len(positions)]


def python_q_learning(player: CyberPlayer, session: tuple, rng: np.random.Generator) -> int:
    """Plain Python Q-learning over one session (the same algorithm, no compilation)."""
    px, pv, tx, tv = session
    q, disc = player.q_table_, player.discretisation_
    alpha, beta, gamma, omega = player.hkb_
    actions, h = list(DEFAULT_ACTIONS), CONTROL_PERIOD / 3

    def acc(x: float, v: float, u: float) -> float:
        return -(alpha * x * x + beta * v * v - gamma) * v - omega * omega * x + u

    def cell(x: float, v: float, k: int) -> int:
        index = 0
        for f, e in zip((x - px[k], v - pv[k], px[k], pv[k]), disc.edges, strict=True):
            index = index * (len(e) + 1) + sum(1 for edge in e if f >= edge)
        return index

    x, v = tx[0], tv[0]
    for k in range(len(px) - 1):
        s = cell(x, v, k)
        a = int(rng.integers(0, 9)) if rng.random() < 0.1 else int(np.argmax(q[s]))
        u = actions[a]
        for _ in range(3):
            a1 = acc(x, v, u)
            x2, v2 = x + h / 2 * v, v + h / 2 * a1
            a2 = acc(x2, v2, u)
            x3, v3 = x + h / 2 * v2, v + h / 2 * a2
            a3 = acc(x3, v3, u)
            x4, v4 = x + h * v3, v + h * a3
            a4 = acc(x4, v4, u)
            x, v = x + h / 6 * (v + 2 * v2 + 2 * v3 + v4), v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
        if x > 0.5:
            x, v = 0.5, min(v, 0.0)
        elif x < -0.5:
            x, v = -0.5, max(v, 0.0)
        r = -((x - tx[k + 1]) ** 2) - 0.1 * (v - tv[k + 1]) ** 2 - 1e-4 * u * u
        q[s, a] += 0.1 * (r + 0.95 * max(q[cell(x, v, k + 1)]) - q[s, a])
    return len(px) - 1


def run(quick: bool) -> list[dict]:
    train = follower_sessions("slow")
    positions, velocities = train
    n_steps = positions.shape[2] - 1
    n_sessions = 100 if quick else 1000

    QLearner(random_state=0, progress=False).train(CyberPlayer(), cycle(train, 1))  # compile
    player = CyberPlayer()
    tracemalloc.start()
    start = time.perf_counter()
    QLearner(random_state=0, progress=False).train(player, cycle(train, n_sessions))
    compiled = time.perf_counter() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    updates_per_s = n_sessions * n_steps / compiled

    subset = 200 if quick else 1000
    session = (positions[0, 0, :subset], velocities[0, 0, :subset], positions[0, 1, :subset],
               velocities[0, 1, :subset])  # fmt: skip
    start = time.perf_counter()
    done = python_q_learning(player, session, np.random.default_rng(0))
    python_rate = done / (time.perf_counter() - start)

    rows = [
        {
            "name": "compiled Q-learning updates",
            "value": updates_per_s,
            "unit": "updates/s",
            "baseline": python_rate,
            "ratio": updates_per_s / python_rate,
            "peak_memory_mb": peak / 2**20,
            "note": f"{n_sessions} sessions x {n_steps} steps; plain Python on {done} steps",
        },
        {
            "name": "compiled training sessions (60 s at T = 0.03 s)",
            "value": n_sessions / compiled,
            "unit": "sessions/s",
            "baseline": python_rate / n_steps,
            "ratio": updates_per_s / python_rate,
            "note": "QLearner.train incl. streaming, learning curve; 1 core",
        },
    ]
    rows += _latency_rows(player)
    rows += _quality_rows(train, follower_sessions("slow"), quick)
    rows.append(
        {
            "name": "process peak resident memory",
            "value": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "unit": "MB",
        }
    )
    return rows


def _latency_rows(player: CyberPlayer) -> list[dict]:
    player.reset()
    n = 100_000
    decide = timeit.timeit(lambda: player.decide(0.1, 0.2, 0.15, 0.25), number=n) / n
    step = timeit.timeit(lambda: player.step(0.15, 0.25), number=n) / n
    return [
        {"name": "policy decision (decide)", "value": decide * 1e6, "unit": "us",
         "note": "target < 10 us; Python call into one compiled function"},
        {"name": "player step (decide + RK4 over T)", "value": step * 1e6, "unit": "us"},
    ]  # fmt: skip


def _quality_rows(
    train: tuple[np.ndarray, np.ndarray], sessions: tuple[np.ndarray, np.ndarray], quick: bool
) -> list[dict]:
    """Train on slow trials 1-7, test on 8-9: RMS to the target for each feature set."""
    fit = (train[0][:7], train[1][:7])
    test = [(sessions[0][7:], sessions[1][7:])]
    copy = math.sqrt(float(np.mean((test[0][0][:, 0] - test[0][0][:, 1]) ** 2)))
    untrained = CyberPlayer()
    untrained.initialise_q(0, 1e-3)
    rows = [
        {"name": "held-out RMS: copy the partner", "value": copy, "unit": "units"},
        {"name": "held-out RMS: untrained (random Q)", "value": untrained.evaluate(test)[1].mean(),
         "unit": "units"},
    ]  # fmt: skip
    n_sessions = 300 if quick else 2000
    for features in ("relative", "absolute"):
        seeds = []
        for seed in range(3):
            player = CyberPlayer(make_default_discretisation(features))
            QLearner(random_state=seed, progress=False).train(player, cycle(fit, n_sessions))
            seeds.append(player.evaluate(test)[1].mean())
        rows.append(
            {
                "name": f"held-out RMS: trained, {features} features",
                "value": float(np.mean(seeds)),
                "unit": "units",
                "baseline": copy,
                "ratio": float(np.mean(seeds)) / copy,
                "note": f"{n_sessions} sessions, mean of 3 seeds (range "
                f"{min(seeds):.4f}-{max(seeds):.4f}); ratio vs copy",
            }
        )
    return rows
