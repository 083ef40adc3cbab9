"""Groups: sessions per second for groups of 4 and 10, group training throughput and memory.

Groups of virtual trainers with the group preset (METHODS section 8, signatures of the two bundled
styles in turn) play 60 s sessions on a new random connected graph each, on the batch engine (2
local threads). The baseline is dyads of the same players and length in the same run: a group
of N does the work of N / 2 dyads, so the ratio says what the coupling graph costs per player.
Group training (`train_group_cyber_player`, a group of four) is timed untraced, and its peak
traced memory compared between a short and a longer run of their own (streaming keeps it flat).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from mirror_avatar.dynamics import GROUP
from mirror_avatar.engine.batch import run_sessions
from mirror_avatar.players import VirtualTrainer
from mirror_avatar.sessions.graphs import random_connected_graph
from mirror_avatar.specs import bundled_generator
from mirror_avatar.training.imitation import train_group_cyber_player

sys.path.insert(0, str(Path(__file__).parent))
from traced import peak_traced_mb  # noqa: E402

SESSION_SECONDS = 60.0


def lineup(n: int) -> list[VirtualTrainer]:
    """``n`` group members with the bundled fast and slow signatures in turn."""
    styles = (bundled_generator("fast"), bundled_generator("slow"))
    return [VirtualTrainer(GROUP, styles[i % 2]) for i in range(n)]


def sessions_per_second(players: list[VirtualTrainer], n_sessions: int, graph: object) -> float:
    start = time.perf_counter()
    for _ in run_sessions(
        [players], n_sessions, SESSION_SECONDS, seed=0, n_jobs=2, chunk_size=10, progress=False,
        graph=graph,  # type: ignore[arg-type]
    ):  # fmt: skip
        pass
    return n_sessions / (time.perf_counter() - start)


def train_group(n_sessions: int) -> None:
    """Train a group member (slow signature, among fast, slow, slow) on ``n_sessions``."""
    fast, slow = bundled_generator("fast"), bundled_generator("slow")
    train_group_cyber_player(slow, [fast, slow, slow], n_sessions=n_sessions, progress=False)


def timed_training(n_sessions: int) -> float:
    """Seconds of `train_group` (untraced)."""
    start = time.perf_counter()
    train_group(n_sessions)
    return time.perf_counter() - start


def run(quick: bool) -> list[dict]:
    n = 40 if quick else 200
    for size in (2, 4):  # load the compiled loop in both workers
        sessions_per_second(lineup(size), 20, random_connected_graph)
    dyads = sessions_per_second(lineup(2), n, None)
    rows = []
    for size in (4, 10):
        groups = sessions_per_second(lineup(size), max(n * 2 // size, 4), random_connected_graph)
        per_dyad = dyads / (size / 2)
        rows.append(
            {
                "name": f"group sessions of {size} players, 60 s, random graphs",
                "value": groups,
                "unit": "sessions/s",
                "baseline": per_dyad,
                "ratio": groups / per_dyad,
                "note": f"baseline: {size // 2} dyads of 60 s per group ({dyads:.1f} dyads/s, "
                "same run); ratio 1 = the graph costs nothing per player; 2 threads",
            }
        )
    short, long = (40, 120) if quick else (200, 800)
    timed_training(4)
    long_s = timed_training(long)
    short_mb = peak_traced_mb(lambda: train_group(short))
    long_mb = peak_traced_mb(lambda: train_group(long))
    rows += [
        {
            "name": "group training, 4 players (generate + Q-learn, streamed)",
            "value": long / long_s,
            "unit": "sessions/s",
            "peak_memory_mb": long_mb,
            "note": f"{long} sessions of 60 s in {long_s:.1f} s, a new random graph each; "
            "memory: a traced run of its own",
        },
        {
            "name": "peak traced memory, long run / short run",
            "value": long_mb / short_mb,
            "unit": "x",
            "baseline": short_mb,
            "peak_memory_mb": long_mb,
            "note": f"{short} vs {long} sessions: about 1 means flat (streaming)",
        },
    ]
    return rows
