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
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.learning.discretisation import make_default_discretisation
from mirror_avatar.learning.training import QLearner
from mirror_avatar.players import Observation
from mirror_avatar.sessions.session import Session
from mirror_avatar.testing import make_follower_sessions, python_learn_session
from mirror_avatar.training.imitation import score_avatar


def follower_sessions(group: str = "slow") -> list[Session]:
    """Dyads from the bundled trials of one style: partner and its 0.3 s late copy."""
    return make_follower_sessions([t for t in load_zhai2017() if t.group == group], lag=0.3)


def cycle(sessions: list[Session], n_sessions: int) -> Iterator[Session]:
    return (sessions[i % len(sessions)] for i in range(n_sessions))


def run(quick: bool) -> list[dict]:
    train = follower_sessions("slow")
    n_steps = train[0].n_samples - 1
    n_sessions = 100 if quick else 1000

    QLearner(CyberPlayer(), random_state=0, progress=False).fit(cycle(train, 1))  # compile
    player = CyberPlayer()
    tracemalloc.start()
    start = time.perf_counter()
    QLearner(player, random_state=0, progress=False).fit(cycle(train, n_sessions))
    compiled = time.perf_counter() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    updates_per_s = n_sessions * n_steps / compiled

    subset = 200 if quick else 1000
    (px, tx), (pv, tv) = train[0].positions[:, :subset], train[0].velocities[:, :subset]
    start = time.perf_counter()
    python_learn_session(player, px, pv, tx, tv, tv, 0.1, 0.95, 0.1, np.random.default_rng(0))
    done = subset - 1
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
            "note": "QLearner.fit incl. streaming, learning curve; 1 core",
        },
    ]
    rows += _latency_rows(player)
    rows += _quality_rows(train, quick)
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
    seen = Observation.of_partner(0, 0.15, 0.25, 0.15)
    disc = player.discretisation_
    decide = timeit.timeit(lambda: disc.index(0.1, 0.2, 0.15, 0.25), number=n) / n
    step = timeit.timeit(lambda: player.step(seen), number=n) / n
    return [
        {"name": "policy decision (state cell)", "value": decide * 1e6, "unit": "us",
         "note": "target < 10 us; Python call into one compiled function"},
        {"name": "player step (cell, best action, RK4 over T)", "value": step * 1e6,
         "unit": "us"},
    ]  # fmt: skip


def _quality_rows(sessions: list[Session], quick: bool) -> list[dict]:
    """Train on slow trials 1-7, test on 8-9: RMS to the target for each feature set."""
    fit, test = sessions[:7], sessions[7:]
    copy = math.sqrt(float(np.mean([(s.positions[0] - s.positions[1]) ** 2 for s in test])))
    untrained = CyberPlayer()
    untrained.initialise_q(0, 1e-3)
    rows = [
        {"name": "held-out RMS: copy the partner", "value": copy, "unit": "units"},
        {"name": "held-out RMS: untrained (random Q)",
         "value": score_avatar(untrained, test)[1].mean(), "unit": "units"},
    ]  # fmt: skip
    n_sessions = 300 if quick else 2000
    for features in ("relative", "absolute"):
        seeds = []
        for seed in range(3):
            player = CyberPlayer(make_default_discretisation(features))
            QLearner(player, random_state=seed, progress=False).fit(cycle(fit, n_sessions))
            seeds.append(score_avatar(player, test)[1].mean())
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
