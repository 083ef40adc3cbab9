"""The virtual trainers' solver on one chunk of paper-scale training: its CPU and its accuracy.

Chunk 0 of ``mirror-avatar train`` (follower, target VT5, partners VT1..VT4, seed 0, 60 s
sessions; `training_stages.chunk_plans` makes the same plans) is played once. Each period's
problems are then rebuilt from the recorded sessions: a trainer's own state, its partner's
position predicted as ``2 x_p(t_k) - x_p(t_{k-1})``, its reference and its partner's velocity.
They are laid out in the engine's lane order, leaders first (`stiffest_first`), and solved
again period by period (`optimal_control_steps`):

- the replay must give the sessions' samples bit for bit, or the script stops;
- its thread CPU is the least of ``--repeats`` replays;
- its solutions (`solve_intervals` at `NEWTON_TOLERANCE`) are compared with the same solver
  run to tolerance ``--tight`` with up to 40 iterations: the control's error relative to
  ``|lambda_2(0)| + eta``, the end velocity's relative to ``|y(T)| + 1`` and the end
  position's (units), over the problems both solve.

``python benchmarks/solver_accuracy.py [--chunk 50] [--repeats 7] [--tight 1e-13]`` prints a
Markdown table.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from numba import njit
from numpy.typing import NDArray
from training_stages import DURATION

from mirror_avatar import dynamics
from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.dynamics import N_SUBSTEPS, optimal_control_steps, solve_intervals
from mirror_avatar.engine.batch import run_chunk
from mirror_avatar.engine.loop import count_samples
from mirror_avatar.training.cast import SEEN_PARTNERS, TARGET, make_virtual_trainers
from mirror_avatar.training.imitation import derive_seeds, make_pairs

Array = NDArray[np.float64]
TIGHT_ITERATIONS = 40


def record(chunk: int) -> tuple[Array, Array, NDArray[np.void], NDArray[np.int64]]:
    """Play chunk 0 and rebuild its problems in lane order, shape (n - 1, 2 chunk, 5).

    Also returns what the sessions recorded for them, shape (n - 1, 2 chunk, 3): position and
    velocity at t_k + T, control at t_k; and the lanes' parameters and rows in them.
    """
    trainers = make_virtual_trainers(load_zhai2017())
    target = trainers[TARGET].generator
    lineups = make_pairs(target, [trainers[i].generator for i in SEEN_PARTNERS], "follower")
    session_seed, _ = derive_seeds(0)
    n = count_samples(DURATION, lineups[0][0].period)
    sessions = run_chunk(lineups, spawn_seeds(session_seed, chunk, bits=64), 0, n)
    x, v, u, r = (
        np.concatenate([getattr(s, name) for s in sessions])
        for name in ("positions", "velocities", "controls", "references")
    )
    partner = np.arange(x.shape[0]) ^ 1
    before = np.concatenate([[0], np.arange(n - 2)])
    problems = np.stack(
        [
            x[:, :-1],
            v[:, :-1],
            2.0 * x[partner, :-1] - x[partner][:, before],
            r[:, :-1],
            v[partner, :-1],
        ],
        axis=-1,
    )
    order = np.concatenate([np.arange(0, x.shape[0], 2), np.arange(1, x.shape[0], 2)])
    recorded = np.stack([x[:, 1:], v[:, 1:], u[:, :-1]], axis=-1)
    params = dynamics.records([lineups[0][0].params, lineups[0][1].params])
    which = np.repeat(np.arange(2), chunk)
    return (
        np.ascontiguousarray(problems[order].transpose(1, 0, 2)),
        np.ascontiguousarray(recorded[order].transpose(1, 0, 2)),
        params,
        which,
    )


@njit(cache=True, nogil=True)
def replay(problems: Array, params: NDArray[np.void], which: NDArray[np.int64], out: Array) -> None:
    """Advance every period's trainers as the engine does (`optimal_control_steps`)."""
    coupled = np.ones(problems.shape[1], np.bool_)
    for k in range(problems.shape[0]):
        optimal_control_steps(problems[k], coupled, params, which, out[k])


@njit(cache=True, nogil=True)
def solve_all(
    problems: Array,
    params: NDArray[np.void],
    which: NDArray[np.int64],
    max_newton: int,
    tolerance: float,
    out: Array,
) -> None:
    """`solve_intervals` of every period's problems at ``tolerance``, into ``out`` (n, L, 5)."""
    coupled = np.ones(problems.shape[1], np.bool_)
    for k in range(problems.shape[0]):
        solve_intervals(
            problems[k], coupled, params, which, N_SUBSTEPS, max_newton, tolerance, out[k]
        )


def errors(solved: Array, tight: Array, eta: Array) -> list[tuple[str, Array]]:
    """Return the errors of ``solved`` against ``tight`` where both converged (name, values)."""
    both = (solved[..., 4] == 1.0) & (tight[..., 4] == 1.0)
    control = np.abs(solved[..., 3] - tight[..., 3]) / (np.abs(tight[..., 3]) + eta)
    velocity = np.abs(solved[..., 1] - tight[..., 1]) / (np.abs(tight[..., 1]) + 1.0)
    position = np.abs(solved[..., 0] - tight[..., 0])
    return [
        ("control, relative to abs(lambda_2(0)) + eta", control[both]),
        ("end velocity, relative to abs(y(T)) + 1", velocity[both]),
        ("end position (units)", position[both]),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--chunk", type=int, default=50, help="sessions in the chunk")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--tight", type=float, default=1e-13, help="the reference's tolerance")
    args = parser.parse_args()
    problems, recorded, params, which = record(args.chunk)
    out = np.empty_like(recorded)
    replay(problems, params, which, out)
    if not np.array_equal(out, recorded, equal_nan=True):
        raise SystemExit("the replay does not give the recorded sessions")
    cpu = []
    for _ in range(args.repeats):
        began = time.thread_time()
        replay(problems, params, which, out)
        cpu.append(time.thread_time() - began)
    solved, tight = (np.empty(problems.shape[:2] + (5,)) for _ in range(2))
    solve_all(problems, params, which, dynamics.MAX_NEWTON, dynamics.NEWTON_TOLERANCE, solved)
    solve_all(problems, params, which, TIGHT_ITERATIONS, args.tight, tight)
    print(
        f"{problems.shape[0] * problems.shape[1]} problems, replayed bit for bit; solver CPU "
        f"{1e3 * min(cpu):.1f} ms (least of {args.repeats}); fallbacks "
        f"{int((solved[..., 4] == 0.0).sum())} (reference {int((tight[..., 4] == 0.0).sum())})"
    )
    print("| error | median | 99th percentile | 99.9th | largest | share above 1e-3 |")
    print("|---|---|---|---|---|---|")
    for name, values in errors(solved, tight, params["eta"][which]):
        q50, q99, q999 = np.quantile(values, [0.5, 0.99, 0.999])
        print(
            f"| {name} | {q50:.2e} | {q99:.2e} | {q999:.2e} | {values.max():.2e} | "
            f"{np.mean(values > 1e-3):.1e} |"
        )


if __name__ == "__main__":
    main()
