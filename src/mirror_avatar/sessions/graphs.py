"""Coupling graphs: who observes whom in a session of N players (METHODS section 8).

A graph is an adjacency matrix ``A`` of shape (N, N) with entries 0 or 1 and a zero diagonal;
``A[k, j] = 1`` means player k observes player j, so player k's neighbours are
``N(k) = {j : A[k, j] = 1}``. Named topologies are undirected (symmetric). A dyad is the complete
graph on two players; a player alone (N = 1) has no neighbour.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.user_files import parse_json, read_text

Graph = NDArray[np.int8]
GraphSource = ArrayLike | Callable[[int, np.random.Generator], ArrayLike] | None
"""A session's graph: fixed (an adjacency matrix), drawn by a function of the number of players
and the session's own random generator (a new graph per session, for instance
`random_connected_graph`), or None for the complete graph."""

TOPOLOGIES = ("complete", "path", "ring", "star", "random")
"""Named topologies `make_graph` builds."""

LINK_PROBABILITY = 0.5
"""Probability of each link in a random graph (METHODS section 8)."""

MAX_GRAPH_BYTES = 2**24
"""Largest graph file read (bytes; 16 MiB, **choice**: the adjacency matrix of 2000 players as
CSV takes 8 MB)."""

MAX_REDRAWS = 10_000
"""Most draws of a random graph before giving up on a connected one."""


def complete_graph(n: int) -> Graph:
    """Make the complete graph: everyone observes everyone else."""
    return _checked_size(n, lambda: np.ones((n, n), dtype=np.int8) - np.eye(n, dtype=np.int8))


def path_graph(n: int) -> Graph:
    """Make a path: players in a line, k observes k - 1 and k + 1."""
    return _checked_size(n, lambda: _band(n, wrap=False))


def ring_graph(n: int) -> Graph:
    """Make a ring: k observes k - 1 and k + 1 modulo n (a path for n < 3)."""
    return _checked_size(n, lambda: _band(n, wrap=n >= 3))


def star_graph(n: int, centre: int = 0) -> Graph:
    """Make a star: the centre observes everyone, everyone else observes the centre only."""
    if not 0 <= centre < max(n, 1):
        raise InputError("graph", f"the centre {centre} is not one of the {n} players")

    def build() -> Graph:
        adjacency = np.zeros((n, n), dtype=np.int8)
        adjacency[centre, :] = adjacency[:, centre] = 1
        adjacency[centre, centre] = 0
        return adjacency

    return _checked_size(n, build)


def random_connected_graph(
    n: int, rng: np.random.Generator, probability: float = LINK_PROBABILITY
) -> Graph:
    """Each pair linked with ``probability``, redrawn until the graph is connected.

    Parameters
    ----------
    n
        Number of players.
    rng
        The source of randomness (a session's own generator, so each session has its graph).
    probability
        Probability of each undirected link, in (0, 1].
    """
    if not 0.0 < probability <= 1.0:
        raise InputError("graph", f"link probability must lie in (0, 1], got {probability}")
    upper = np.triu_indices(n, k=1)
    for _ in range(MAX_REDRAWS):
        adjacency = np.zeros((n, n), dtype=np.int8)
        adjacency[upper] = rng.random(upper[0].size) < probability
        adjacency |= adjacency.T
        if is_connected(adjacency):
            return adjacency
    raise InputError("graph", f"no connected graph in {MAX_REDRAWS} draws at p = {probability}")


def make_graph(topology: str, n: int, rng: np.random.Generator | None = None) -> Graph:
    """Build a named topology (`TOPOLOGIES`) on ``n`` players; ``random`` needs ``rng``."""
    if topology == "random":
        if rng is None:
            raise InputError("graph", "a random graph needs a random generator")
        return random_connected_graph(n, rng)
    builders: dict[str, Callable[[int], Graph]] = {
        "complete": complete_graph,
        "path": path_graph,
        "ring": ring_graph,
        "star": star_graph,
    }
    if topology not in builders:
        raise InputError("graph", f"unknown topology {topology!r}; expected one of {TOPOLOGIES}")
    return builders[topology](n)


def graph_source(spec: str, n_players: int, connected: bool = True) -> GraphSource:
    """Return the graph a command-line ``--graph`` names, for sessions of ``n_players``.

    Parameters
    ----------
    spec
        A topology of `TOPOLOGIES` (``random``: a new connected graph for every session) or an
        adjacency matrix file (`read_graph`).
    n_players
        The number of players the graph must cover.
    connected
        Whether a graph from a file must be connected.

    Raises
    ------
    InputError
        Naming the file or option and the problem.
    """
    if spec == "random":
        return random_connected_graph
    if spec in TOPOLOGIES:
        return make_graph(spec, n_players)
    path = Path(spec)
    if not path.suffix:
        raise InputError(spec, f"not a topology ({', '.join(TOPOLOGIES)}) or a .csv/.json file")
    try:
        return check_graph(read_graph(path), n_players, connected)
    except InputError as error:
        raise InputError(path, error.problem) from None


def read_graph(path: str | os.PathLike[str]) -> Graph:
    """Read an adjacency matrix from a file.

    CSV: rows of 0 and 1 separated by commas. JSON: a list of rows, or an object whose
    ``"adjacency"`` is one. Validated by `check_graph` without requiring connectedness.

    Raises
    ------
    InputError
        Missing or unreadable file, or not an adjacency matrix.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(path, f"no such file, and not a topology ({', '.join(TOPOLOGIES)})")
    text = read_text(path, MAX_GRAPH_BYTES)
    if path.suffix.lower() == ".json":
        value = parse_json(text, path)
        rows = value.get("adjacency", []) if isinstance(value, dict) else value
    elif path.suffix.lower() == ".csv":
        rows = [line.split(",") for line in text.splitlines() if line.strip()]
    else:
        raise InputError(path, "a graph file must be .csv or .json")
    try:
        return check_graph(rows, connected=False)
    except InputError as error:
        raise InputError(path, error.problem) from None


def draw_graph(source: GraphSource, n_players: int, seed: int) -> Graph:
    """Resolve a `GraphSource` for one session of ``n_players``, drawing from ``seed`` if needed.

    A drawn graph must be connected; a fixed one may leave players alone.
    """
    if source is None:
        return complete_graph(n_players)
    if callable(source):
        return check_graph(source(n_players, np.random.default_rng(seed)), n_players)
    return check_graph(source, n_players, connected=False)


def check_graph(
    adjacency: ArrayLike, n_players: int | None = None, connected: bool = True
) -> Graph:
    """Validate an adjacency matrix and return it as int8.

    Parameters
    ----------
    adjacency
        Square matrix of 0 and 1 with a zero diagonal.
    n_players
        The number of players it must cover, if known.
    connected
        Whether the graph must be connected (ignoring the direction of links).

    Raises
    ------
    InputError
        Naming the first problem found.
    """
    try:
        matrix = np.asarray(adjacency, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("graph", "the adjacency matrix must be numeric") from None
    if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1] or matrix.shape[0] == 0:
        raise InputError("graph", f"the adjacency matrix must be square, got shape {matrix.shape}")
    if n_players is not None and matrix.shape[0] != n_players:
        raise InputError("graph", f"{matrix.shape[0]} rows for {n_players} players")
    if not ((matrix == 0) | (matrix == 1)).all():
        raise InputError("graph", "adjacency entries must be 0 or 1")
    if matrix.diagonal().any():
        raise InputError("graph", "a player cannot observe itself: the diagonal must be 0")
    graph = matrix.astype(np.int8)
    if connected and not is_connected(graph):
        raise InputError("graph", "the graph is not connected")
    return graph


def is_connected(adjacency: ArrayLike) -> bool:
    """Whether every player reaches every other one, ignoring the direction of links."""
    links = np.asarray(adjacency) != 0
    links = links | links.T
    reached = np.zeros(links.shape[0], dtype=bool)
    reached[0] = True
    frontier = reached.copy()
    while frontier.any():
        frontier = links[frontier].any(axis=0) & ~reached
        reached |= frontier
    return bool(reached.all())


def neighbours(adjacency: ArrayLike, player: int) -> NDArray[np.int64]:
    """Return the indices of the players ``player`` observes, in increasing order."""
    return np.flatnonzero(np.asarray(adjacency)[player]).astype(np.int64)


def _band(n: int, wrap: bool) -> Graph:
    adjacency = np.zeros((n, n), dtype=np.int8)
    for k in range(n - 1):
        adjacency[k, k + 1] = adjacency[k + 1, k] = 1
    if wrap:
        adjacency[0, n - 1] = adjacency[n - 1, 0] = 1
    return adjacency


def _checked_size(n: int, build: Callable[[], Graph]) -> Graph:
    if not (isinstance(n, int | np.integer) and n >= 1):
        raise InputError("graph", f"the number of players must be a positive integer, got {n!r}")
    return build()
