"""The batch engine: many virtual-trainer sessions in compiled code, streamed in chunks.

A session between two virtual trainers is one compiled loop (`run_trainer_session`) calling the
same `mirror_avatar.hkb.optimal_control_step` as `VirtualTrainer.step`, with the same partner
prediction and the same references, so a batch session is identical to `mirror_avatar.game.play`
of the same two players with the same seed. Sessions are grouped in chunks run on local processes
(joblib) or on a Dask cluster, and yielded in order as `SessionBatch` arrays: a 24 000-session run
never holds more than a few chunks in memory. Session ``i`` uses ``pairs[i % len(pairs)]`` and the
seed ``session_seeds(seed, n)[i]``, so results depend neither on the chunk size nor on the backend.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from joblib import Parallel, delayed
from numba import njit
from numpy.typing import NDArray
from tqdm.auto import tqdm

from mirror_avatar.errors import InputError
from mirror_avatar.game import player_seeds
from mirror_avatar.hkb import optimal_control_step
from mirror_avatar.players import VirtualTrainer

DASK_CONNECT_TIMEOUT = 10.0
"""Seconds to wait for a Dask scheduler before giving up."""

Array = NDArray[np.float64]
Pair = tuple[VirtualTrainer, VirtualTrainer]


@dataclass(eq=False)
class SessionBatch:
    """A chunk of consecutive sessions, all arrays at the control period.

    Attributes
    ----------
    positions, velocities, controls, references
        Shape (k, 2, n): session, player (0 and 1 of the pair), sample; units, units/s,
        units/s², units/s. Controls and references of the last sample are NaN (as in `Session`).
    period
        Control period (s).
    start
        Index of the chunk's first session in the run.
    pair_index
        Which pair played each session, shape (k,).
    seeds
        Each session's seed, shape (k,) (pass it to `mirror_avatar.game.play` to replay it).
    """

    positions: Array
    velocities: Array
    controls: Array
    references: Array
    period: float
    start: int
    pair_index: NDArray[np.int64]
    seeds: NDArray[np.uint64]

    def __len__(self) -> int:
        """Return the number of sessions in the chunk."""
        return int(self.positions.shape[0])


@njit(cache=True)
def run_trainer_session(params: Array, references: Array, starts: Array, out: Array) -> None:
    """Play one session between two virtual trainers, writing into ``out``.

    Parameters
    ----------
    params
        Both players' `HKBParams.as_vector`, shape (2, 8).
    references
        Both players' reference velocities at the control times, shape (2, n - 1).
    starts
        Initial position and velocity of each player, shape (2, 2).
    out
        Shape (4, 2, n): positions, velocities, controls, references.
    """
    n = out.shape[2]
    out[:, :, :] = np.nan
    for player in range(2):
        out[0, player, 0] = starts[player, 0]
        out[1, player, 0] = starts[player, 1]
    for k in range(n - 1):
        for player in range(2):
            partner = 1 - player
            observed = out[0, partner, k]
            previous = out[0, partner, k - 1] if k > 0 else observed
            x, v, u = optimal_control_step(
                out[0, player, k],
                out[1, player, k],
                2.0 * observed - previous,
                references[player, k],
                out[1, partner, k],
                params[player],
            )
            out[0, player, k + 1] = x
            out[1, player, k + 1] = v
            out[2, player, k] = u
            out[3, player, k] = references[player, k]


def session_seeds(seed: int | None, n_sessions: int) -> NDArray[np.uint64]:
    """Independent per-session seeds spawned from ``seed``, shape (n_sessions,)."""
    children = np.random.SeedSequence(seed).spawn(n_sessions)
    return np.array([c.generate_state(1, np.uint64)[0] for c in children], dtype=np.uint64)


def run_chunk(
    pairs: Sequence[Pair], seeds: NDArray[np.uint64], start: int, n_samples: int
) -> SessionBatch:
    """Play sessions ``start .. start + len(seeds) - 1`` of a run (in the calling process)."""
    k = seeds.size
    out = np.empty((k, 4, 2, n_samples))
    pair_index = (start + np.arange(k)) % len(pairs)
    for i in range(k):
        first, second = pairs[pair_index[i]]
        _, seed_a, seed_b = player_seeds(int(seeds[i]))
        references = np.vstack(
            [
                first.draw_reference(seed_a, n_samples - 1),
                second.draw_reference(seed_b, n_samples - 1),
            ]
        )
        params = np.vstack([first.params.as_vector(), second.params.as_vector()])
        starts = np.array([first.start, second.start], dtype=np.float64)
        run_trainer_session(params, references, starts, out[i])
    return SessionBatch(
        out[:, 0],
        out[:, 1],
        out[:, 2],
        out[:, 3],
        float(pairs[0][0].period),
        start,
        pair_index.astype(np.int64),
        seeds,
    )


def run_sessions(
    pairs: Sequence[Pair],
    n_sessions: int,
    duration: float = 60.0,
    seed: int | None = 0,
    backend: Literal["local", "dask"] = "local",
    scheduler: str | None = None,
    n_jobs: int = 2,
    chunk_size: int = 50,
    progress: bool | None = None,
) -> Iterator[SessionBatch]:
    """Run many virtual-trainer sessions and yield them in order, a chunk at a time.

    Parameters
    ----------
    pairs
        ``(player 0, player 1)`` virtual trainers; session i uses ``pairs[i % len(pairs)]``.
    n_sessions
        Number of sessions.
    duration
        Session length (s).
    seed
        Seed of the run (session seeds are spawned from it with `session_seeds`).
    backend
        ``"local"``: joblib processes on this machine (``n_jobs=1`` runs in this process);
        ``"dask"``: the Dask cluster at ``scheduler``.
    scheduler
        Address of a Dask scheduler (``tcp://host:port``); required for ``backend="dask"``.
    n_jobs
        Local worker processes.
    chunk_size
        Sessions per chunk (the unit of work and of memory: about 2 MB per 50 sessions of 60 s).
    progress
        tqdm progress bar over sessions: True, False, or None (only on a terminal).

    Yields
    ------
    SessionBatch
        Consecutive chunks; the last may be shorter.
    """
    _check_run(pairs, n_sessions, chunk_size, backend, scheduler)
    period = float(pairs[0][0].period)
    n_samples = int(round(duration / period)) + 1
    seeds = session_seeds(seed, n_sessions)
    starts = range(0, n_sessions, chunk_size)
    tasks = ((list(pairs), seeds[s : s + chunk_size], s, n_samples) for s in starts)
    if backend == "dask":
        results = _run_on_dask(tasks, str(scheduler))
    elif n_jobs == 1:
        results = (run_chunk(*task) for task in tasks)
    else:
        parallel = Parallel(n_jobs=n_jobs, return_as="generator", pre_dispatch="2*n_jobs")
        results = parallel(delayed(run_chunk)(*task) for task in tasks)
    with tqdm(total=n_sessions, disable=_quiet(progress), unit="session") as bar:
        for batch in results:
            bar.update(len(batch))
            yield batch


def _check_run(
    pairs: Sequence[Pair], n_sessions: int, chunk_size: int, backend: str, scheduler: str | None
) -> None:
    if not pairs:
        raise InputError("pairs", "no pairs of players to run")
    periods = {float(p.period) for pair in pairs for p in pair}
    if len(periods) != 1:
        raise InputError("pairs", f"all players need the same control period, got {periods}")
    for pair in pairs:
        for player in pair:
            if not isinstance(player, VirtualTrainer):
                raise InputError("pairs", f"the batch engine runs virtual trainers, not {player!r}")
    if n_sessions < 1 or chunk_size < 1:
        raise InputError("sessions", "n_sessions and chunk_size must be positive")
    if backend not in ("local", "dask"):
        raise InputError("backend", f"unknown backend {backend!r}; expected local or dask")
    if backend == "dask" and not scheduler:
        raise InputError("backend", "the dask backend needs a scheduler address")


def _run_on_dask(tasks: Iterator[tuple[Any, ...]], scheduler: str) -> Iterator[SessionBatch]:
    """Submit chunks to a Dask cluster, keeping a few in flight, and yield them in order."""
    from distributed import Client

    try:
        client = Client(scheduler, timeout=DASK_CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as error:
        raise InputError(scheduler, f"cannot reach the Dask scheduler ({error})") from None
    with client:
        in_flight: deque[Any] = deque()
        window = 2 * max(sum(client.nthreads().values()), 1)
        pairs_future = None
        for pairs, seeds, start, n_samples in tasks:
            if pairs_future is None:
                pairs_future = client.scatter(pairs, broadcast=True)
            in_flight.append(client.submit(run_chunk, pairs_future, seeds, start, n_samples))
            if len(in_flight) >= window:
                yield in_flight.popleft().result()
        while in_flight:
            yield in_flight.popleft().result()


def _quiet(progress: bool | None) -> bool | None:
    return None if progress is None else not progress
