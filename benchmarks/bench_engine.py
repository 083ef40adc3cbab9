"""Game engine: virtual-trainer sessions per second, against a per-step solve_bvp baseline.

The batch engine (`mirror_avatar.engine.batch.run_sessions`, the compiled loop on local threads)
plays 60 s leader-vs-follower sessions between virtual trainers driven by the bundled "fast" and
"slow" IMS generators. The baseline solves the same optimal-control step the straightforward way,
as the original MATLAB implementation did with bvp4c: scipy's ``solve_bvp`` on the nonlinear
two-point boundary value problem at every step, timed on a few steps in the same run. Also: the
compiled step alone, one live `VirtualTrainer.step` call, peak memory, and the projected time of
the paper's 24 000 training sessions.
"""

from __future__ import annotations

import os
import resource
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from mirror_avatar.dynamics import (
    FOLLOWER,
    LEADER,
    MAX_NEWTON,
    N_SUBSTEPS,
    NEWTON_TOLERANCE,
    HKBParams,
    clip_to_range,
    solve_interval,
)
from mirror_avatar.engine.batch import run_sessions
from mirror_avatar.players import Observation, VirtualTrainer
from mirror_avatar.sessions.session import Session
from mirror_avatar.specs import bundled_generator
from mirror_avatar.testing import solve_step_bvp

sys.path.insert(0, str(Path(__file__).parent))
from traced import peak_traced_mb  # noqa: E402

PAPER_SESSIONS = 24_000
SESSION_SECONDS = 60.0


def solve_step_bvp_like_bvp4c(
    params: HKBParams, x0: float, y0: float, rp: float, rs: float, rv: float
) -> tuple[float, float, float]:
    """One optimal-control step the bvp4c way: tolerance 1e-3, a mesh of 10 nodes, clipped."""
    x_end, y_end, u0 = solve_step_bvp(params, x0, y0, rp, rs, rv, tol=1e-3, n_nodes=10)
    return (*clip_to_range(x_end, y_end), u0)


def make_pairs() -> list[tuple[VirtualTrainer, VirtualTrainer]]:
    """Leader and follower virtual trainers over the two bundled styles (4 pairs)."""
    fast, slow = bundled_generator("fast"), bundled_generator("slow")
    return [
        (VirtualTrainer(LEADER, lead), VirtualTrainer(FOLLOWER, follow))
        for lead in (fast, slow)
        for follow in (fast, slow)
    ]


def measure_batch(
    pairs: list[tuple[VirtualTrainer, VirtualTrainer]], n_sessions: int, n_jobs: int
) -> tuple[float, np.ndarray]:
    """Seconds for ``n_sessions`` of 60 s (untraced) and the first session's positions."""
    start = time.perf_counter()
    first = None
    for chunk in run_batch(pairs, n_sessions, n_jobs):
        first = chunk[0].positions if first is None else first
    elapsed = time.perf_counter() - start
    assert first is not None
    return elapsed, first


def run_batch(
    pairs: list[tuple[VirtualTrainer, VirtualTrainer]], n_sessions: int, n_jobs: int
) -> Iterator[list[Session]]:
    """Start the benchmark's batch run: sessions of 60 s in chunks of 25."""
    return run_sessions(
        pairs, n_sessions, SESSION_SECONDS, seed=0, n_jobs=n_jobs, chunk_size=25, progress=False
    )


def step_inputs(positions: np.ndarray, n: int) -> list[tuple[float, float, float, float, float]]:
    """``n`` follower steps taken from a played session: (x, y, r_p, r_s, r_v) at human speeds."""
    rng = np.random.default_rng(0)
    leader, follower = positions
    ks = rng.choice(np.arange(1, leader.size - 1), n, replace=False)
    period = LEADER.period
    return [
        (
            float(follower[k]),
            float((follower[k] - follower[k - 1]) / period),
            float(2 * leader[k] - leader[k - 1]),
            float(rng.uniform(-0.5, 0.5)),
            0.0,
        )
        for k in ks
    ]


def control_step(
    x: float, y: float, rp: float, rs: float, rv: float, params: np.ndarray
) -> tuple[float, float]:
    """One coupled optimal-control step from Python: clipped end position and velocity."""
    x_end, y_end, *_ = solve_interval(
        x, y, rp, rs, rv, params, True, N_SUBSTEPS, MAX_NEWTON, NEWTON_TOLERANCE
    )
    return clip_to_range(x_end, y_end)


def run(quick: bool) -> list[dict]:
    pairs = make_pairs()
    n_jobs = 2
    for jobs in (1, n_jobs):  # load the compiled code
        list(run_sessions(pairs, 2 * jobs, 1.0, n_jobs=jobs, chunk_size=1, progress=False))
    n_sessions = 200 if quick else 2000
    elapsed, positions = measure_batch(pairs, n_sessions, n_jobs)
    sessions_per_s = n_sessions / elapsed
    peak_mb = peak_traced_mb(lambda: list(run_batch(pairs, n_sessions // 4, n_jobs)))
    inline, _ = measure_batch(pairs, n_sessions // 10, 1)
    inline_per_s = n_sessions // 10 / inline
    steps_per_session = 2 * int(round(SESSION_SECONDS / LEADER.period))

    inputs = step_inputs(positions, 10 if quick else 30)
    p = FOLLOWER.record()
    start = time.perf_counter()
    baseline = [solve_step_bvp_like_bvp4c(FOLLOWER, *args) for args in inputs]
    bvp_step = (time.perf_counter() - start) / len(inputs)
    velocity_gap = max(
        abs(control_step(*args, p)[1] - b[1]) for args, b in zip(inputs, baseline, strict=True)
    )
    n_repeat = 20_000
    start = time.perf_counter()
    for _ in range(n_repeat // len(inputs)):
        for x, y, rp, rs, rv in inputs:
            control_step(x, y, rp, rs, rv, p)
    step = (time.perf_counter() - start) / (n_repeat // len(inputs) * len(inputs))
    bvp_sessions_per_s = 1.0 / (bvp_step * steps_per_session)

    trainer = pairs[0][1]
    trainer.reset(seed=0)
    seen = [Observation.of_partner(k, 0.1 * np.sin(0.03 * k), 0.0, 0.0) for k in range(1000)]
    for observation in seen[:10]:  # load the compiled step in this process
        trainer.step(observation)
    start = time.perf_counter()
    for observation in seen:
        trainer.step(observation)
    live_step = (time.perf_counter() - start) / 1000

    projected = PAPER_SESSIONS / sessions_per_s
    return [
        {
            "name": "batch engine: VT-vs-VT sessions of 60 s",
            "value": sessions_per_s,
            "unit": "sessions/s",
            "baseline": bvp_sessions_per_s,
            "ratio": sessions_per_s / bvp_sessions_per_s,
            "peak_memory_mb": peak_mb,
            "note": f"{n_sessions} sessions, {n_jobs} threads (cores: {os.cpu_count()}), "
            "chunks of 25; baseline = solve_bvp per step (1 core), projected from "
            f"{len(inputs)} steps; memory: a traced run of {n_sessions // 4} sessions",
        },
        {
            "name": "batch engine in this process (n_jobs=1)",
            "value": inline_per_s,
            "unit": "sessions/s",
            "baseline": bvp_sessions_per_s,
            "ratio": inline_per_s / bvp_sessions_per_s,
            "note": f"{n_sessions // 10} sessions, 1 core",
        },
        {
            "name": f"projected time for {PAPER_SESSIONS} sessions of 60 s",
            "value": projected / 60.0,
            "unit": "min",
            "baseline": PAPER_SESSIONS / bvp_sessions_per_s / 3600.0,
            "note": "target < 2 min on 2 cores; baseline column in hours (1 core)",
        },
        {
            "name": "optimal-control step (compiled, called from Python)",
            "value": step * 1e6,
            "unit": "us",
            "baseline": bvp_step * 1e6,
            "ratio": bvp_step / step,
            "note": "follower steps at states from a played session; baseline = solve_bvp",
        },
        {
            "name": "largest end-velocity difference, compiled step vs solve_bvp",
            "value": velocity_gap,
            "unit": "units/s",
            "note": "the same problem; solve_bvp at bvp4c's default tolerance 1e-3",
        },
        {
            "name": "compiled step inside the batch loop (derived)",
            "value": 1e6 * n_jobs / (sessions_per_s * steps_per_session),
            "unit": "us per step per core",
            "note": "batch wall time x threads / steps, incl. reference drawing",
        },
        {
            "name": "live VirtualTrainer.step",
            "value": live_step * 1e6,
            "unit": "us",
            "note": "budget 30 000 us (the control period)",
        },
        {
            "name": "process peak resident memory",
            "value": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "unit": "MB",
        },
    ]
