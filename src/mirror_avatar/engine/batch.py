"""The batch engine: many sessions in the compiled loop, streamed in chunks from many workers.

A chunk of sessions of built-in players (`mirror_avatar.players.base.Player.plan`) is one call
of the compiled loop (`mirror_avatar.engine.compiled.run_plans`), the sessions side by side, and
the loop calls the same step kernels as the players' own ``step``, so a batch session is
identical to `mirror_avatar.engine.loop.play` of the same players with the same seed. Chunks run
on threads of this process (the compiled code releases the GIL, and nothing is pickled) or on a
Dask cluster, and are yielded in order as lists of `mirror_avatar.sessions.session.Session`:
a 24 000-session run never holds more than a few chunks in memory. Session ``i`` uses
``lineups[i % len(lineups)]`` and the seed ``spawn_seeds(seed, n, bits=64)[i]``, so results depend
neither on the chunk size nor on where they are played. The graph may be fixed or drawn for
each session.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.progress import progress_bar
from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.engine.compiled import run_plans
from mirror_avatar.engine.loop import check_lineup, count_samples, spawn_session_seeds
from mirror_avatar.players.base import Player, PlayerPlan
from mirror_avatar.sessions.graphs import Graph, GraphSource, draw_graph
from mirror_avatar.sessions.session import Session, default_roles

DASK_CONNECT_TIMEOUT = 10.0
"""Seconds to wait for a Dask scheduler before giving up."""

Lineup = Sequence[Player]


def play_compiled(
    players: Lineup,
    n_samples: int,
    seed: int,
    graph: GraphSource = None,
    roles: Sequence[str] | None = None,
) -> Session:
    """Play one session in the compiled loop, as `mirror_avatar.engine.loop.play` would."""
    return play_compiled_together([players], [seed], n_samples, graph, roles)[0]


def play_compiled_together(
    lineups: Sequence[Lineup],
    seeds: Sequence[int],
    n_samples: int,
    graph: GraphSource = None,
    roles: Sequence[str] | None = None,
) -> list[Session]:
    """Play sessions side by side in one call of the compiled loop; session i: ``lineups[i]``.

    The sessions are the blocks of one block-diagonal graph, so every period the virtual
    trainers of all of them are solved together (`mirror_avatar.dynamics.optimal_control_steps`,
    vectorised across problems); each session is the one `play_compiled` gives alone, and owns
    its arrays (a session kept alone does not hold the whole chunk's): its four channels are
    the rows of one copy of its block.
    """
    period = check_lineup(lineups[0])
    blocks = [
        _plan_session(players, n_samples, seed, graph)
        for players, seed in zip(lineups, seeds, strict=True)
    ]
    plans = [plan for session_plans, _, _ in blocks for plan in session_plans]
    together = np.zeros((len(plans), len(plans)), dtype=np.int8)
    rows: list[slice] = []
    for _, adjacency, player_seeds in blocks:
        first = rows[-1].stop if rows else 0
        rows.append(slice(first, first + len(player_seeds)))
        together[rows[-1], rows[-1]] = adjacency
    out = run_plans(plans, together, n_samples)
    times = np.arange(n_samples, dtype=np.float64) * period
    return [
        _session(out[:, block].copy(), times, players, roles, adjacency, seed, player_seeds)
        for players, seed, (_, adjacency, player_seeds), block in zip(
            lineups, seeds, blocks, rows, strict=True
        )
    ]


def _session(
    channels: NDArray[np.float64],
    times: NDArray[np.float64],
    players: Lineup,
    roles: Sequence[str] | None,
    graph: Graph,
    seed: int,
    player_seeds: list[int],
) -> Session:
    """Make a session of its channels (4, N, n): positions, velocities, controls, references."""
    positions, velocities, controls, references = channels
    return Session(
        times,
        positions,
        velocities,
        controls,
        references,
        labels=tuple(p.label or f"player {i}" for i, p in enumerate(players)),
        roles=tuple(roles) if roles is not None else default_roles(len(players)),
        graph=graph,
        metadata={
            "seed": seed,
            "player_seeds": player_seeds,
            "players": [p.describe() for p in players],
        },
    )


def _plan_session(
    players: Lineup, n_samples: int, seed: int, graph: GraphSource
) -> tuple[list[PlayerPlan], Graph, list[int]]:
    """Return a session's player plans, graph and player seeds, as `play` draws them."""
    check_lineup(players)
    seeds, graph_seed = spawn_session_seeds(seed, len(players))
    adjacency = draw_graph(graph, len(players), graph_seed)
    plans = [p.plan(s, n_samples - 1) for p, s in zip(players, seeds, strict=True)]
    missing = [type(p).__name__ for p, plan in zip(players, plans, strict=True) if plan is None]
    if missing:
        raise InputError("players", f"the compiled engine cannot run {', '.join(missing)}")
    return plans, adjacency, seeds  # type: ignore[return-value]


def run_chunk(
    lineups: Sequence[Lineup],
    seeds: NDArray[np.uint64],
    start: int,
    n_samples: int,
    graph: GraphSource = None,
    roles: Sequence[str] | None = None,
) -> list[Session]:
    """Play sessions ``start .. start + len(seeds) - 1`` of a run together (in this process)."""
    indices = [(start + offset) % len(lineups) for offset in range(len(seeds))]
    sessions = play_compiled_together(
        [lineups[i] for i in indices], [int(s) for s in seeds], n_samples, graph, roles
    )
    for offset, (session, index) in enumerate(zip(sessions, indices, strict=True)):
        session.metadata |= {"session": start + offset, "lineup": index}
    return sessions


def run_sessions(
    lineups: Sequence[Lineup],
    n_sessions: int,
    duration: float = 60.0,
    seed: int | None = 0,
    scheduler: str | None = None,
    n_jobs: int = 2,
    chunk_size: int = 50,
    progress: bool | None = None,
    graph: GraphSource = None,
    roles: Sequence[str] | None = None,
) -> Iterator[list[Session]]:
    """Run many sessions in the compiled loop and yield them in order, a chunk at a time.

    Parameters
    ----------
    lineups
        Players of each kind of session (virtual trainers, recordings, cyber players); session
        i uses ``lineups[i % len(lineups)]``.
    n_sessions
        Number of sessions.
    duration
        Session length (s).
    seed
        Seed of the run (session seeds are spawned from it).
    scheduler
        Address of the Dask scheduler (``tls://host:port`` or ``tcp://host:port``) whose
        cluster plays the sessions; None plays them on ``n_jobs`` threads of this process.
    n_jobs
        Local worker threads (``1`` plays in the calling thread).
    chunk_size
        Sessions per chunk (the unit of work and of memory: 6.4 MB of session arrays per 50
        dyads of 60 s, played side by side in one compiled loop).
    progress
        Progress over sessions: True, False, or None (a tqdm bar on a terminal, plain lines off
        one; `mirror_avatar.common.progress.progress_bar`).
    graph
        Who observes whom: a fixed adjacency matrix, a function drawing one for each session
        from its own generator (`mirror_avatar.sessions.graphs.GraphSource`), or None (complete).
    roles
        The players' roles, recorded in every session.

    Yields
    ------
    list of Session
        Consecutive chunks; the last may be shorter.
    """
    period = _check_run(lineups, n_sessions, chunk_size, graph)
    n_samples = count_samples(duration, period)
    seeds = spawn_seeds(seed, n_sessions, bits=64)
    starts = range(0, n_sessions, chunk_size)
    tasks = ((list(lineups), seeds[s : s + chunk_size], s, n_samples, graph, roles) for s in starts)
    if scheduler is not None:
        results = _run_on_dask(tasks, scheduler)
    elif n_jobs == 1:
        results = (run_chunk(*task) for task in tasks)
    else:
        results = _run_on_threads(tasks, n_jobs)
    with progress_bar(n_sessions, "sessions", "session", progress) as bar:
        for chunk in results:
            bar.update(len(chunk))
            yield chunk


def _check_run(
    lineups: Sequence[Lineup],
    n_sessions: int,
    chunk_size: int,
    graph: GraphSource,
) -> float:
    if not lineups:
        raise InputError("lineups", "no players to run")
    periods = set()
    for lineup in lineups:
        periods.add(check_lineup(lineup))
        if not callable(graph):
            draw_graph(graph, len(lineup), 0)
        for player in lineup:
            if type(player).plan is Player.plan:
                raise InputError(
                    "lineups", f"the batch engine cannot run {type(player).__name__} players"
                )
    if len(periods) != 1:
        raise InputError("lineups", f"all players need the same control period, got {periods}")
    if n_sessions < 1 or chunk_size < 1:
        raise InputError("sessions", "n_sessions and chunk_size must be positive")
    return periods.pop()


def _run_on_threads(tasks: Iterator[tuple[Any, ...]], n_jobs: int) -> Iterator[list[Session]]:
    """Run chunks on ``n_jobs`` threads of this process and yield them in order.

    The compiled loop and the reference kernels release the GIL, so the threads run in
    parallel, with nothing pickled between them and the consumer of the chunks.
    """
    pool = ThreadPoolExecutor(n_jobs, thread_name_prefix="mirror-avatar-batch")
    try:
        yield from _in_order((pool.submit(run_chunk, *task) for task in tasks), 2 * n_jobs)
    finally:
        pool.shutdown(wait=False, cancel_futures=True)


TLS_CREDENTIALS = (
    "DASK_DISTRIBUTED__COMM__TLS__CA_FILE",
    "DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT",
    "DASK_DISTRIBUTED__COMM__TLS__CLIENT__KEY",
)
"""Environment variables that give the client its TLS credentials (Dask's configuration keys
``distributed.comm.tls.ca-file``, ``.client.cert`` and ``.client.key``; docs/cluster.md)."""


def connect_to_scheduler(scheduler: str) -> Any:
    """Connect a Dask client to ``scheduler``, waiting `DASK_CONNECT_TIMEOUT`.

    A ``tls://host:port`` address is connected to with the credentials of Dask's configuration
    (`TLS_CREDENTIALS`), a ``tcp://host:port`` one in plain text.

    Raises
    ------
    InputError
        The scheduler cannot be reached, refuses the client's certificate, or is a TLS one and
        the configuration gives no credentials (one line naming its address).
    """
    from distributed import Client

    if scheduler.startswith("tls://"):
        _check_tls_credentials(scheduler)
    try:
        return Client(scheduler, timeout=DASK_CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as error:
        raise InputError(scheduler, f"cannot reach the Dask scheduler ({error})") from None


def _check_tls_credentials(scheduler: str) -> None:
    """Refuse a TLS scheduler when Dask's configuration has no CA file or client certificate."""
    from distributed.security import Security

    tls = Security().get_tls_config_for_role("client")
    if not (tls["ca_file"] and tls["cert"]):
        raise InputError(
            scheduler,
            f"a TLS scheduler needs the client's credentials: set {', '.join(TLS_CREDENTIALS)} "
            "(docs/cluster.md)",
        )


def check_scheduler(scheduler: str) -> None:
    """Connect to ``scheduler`` and disconnect, so a command fails before its work, not after.

    Raises
    ------
    InputError
        The scheduler cannot be reached.
    """
    connect_to_scheduler(scheduler).close()


def _run_on_dask(tasks: Iterator[tuple[Any, ...]], scheduler: str) -> Iterator[list[Session]]:
    """Submit chunks to a Dask cluster, keeping a few in flight, and yield them in order."""
    with connect_to_scheduler(scheduler) as client:
        scattered: list[Any] = []

        def submit(lineups: Sequence[Lineup], *rest: Any) -> Any:
            if not scattered:
                scattered.append(client.scatter(lineups, broadcast=True))
            return client.submit(run_chunk, scattered[0], *rest)

        window = 2 * max(sum(client.nthreads().values()), 1)
        yield from _in_order((submit(*task) for task in tasks), window)


def _in_order(submitted: Iterator[Future[list[Session]]], window: int) -> Iterator[list[Session]]:
    """Yield the results of submitted chunks in order, keeping ``window`` of them in flight."""
    in_flight: deque[Future[list[Session]]] = deque()
    for future in submitted:
        in_flight.append(future)
        if len(in_flight) >= window:
            yield in_flight.popleft().result()
    while in_flight:
        yield in_flight.popleft().result()
