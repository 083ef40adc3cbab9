"""Seeds: every random choice in the toolkit derives from one integer, in one of two ways.

A run seed is turned into the seeds of its parts by `spawn_seeds` (independent child streams of
`numpy.random.SeedSequence`, one per session or per player) or by `draw_seeds` (words drawn from
one stream, for a few fixed parts of a run). `entropy_of` returns the integer a ``None`` seed
actually used, so that it can be recorded and the run replayed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

Seed = int | Sequence[int] | None
"""A seed as `numpy.random.SeedSequence` takes it: an integer, a sequence of them, or None."""


def entropy_of(seed: int | None) -> int:
    """Return ``seed`` itself, or for None the fresh entropy drawn in its place.

    ``spawn_seeds(entropy_of(None), n)`` and a later ``spawn_seeds`` of the recorded entropy
    give the same seeds.
    """
    return int(np.random.SeedSequence(seed).entropy)  # type: ignore[arg-type]


def spawn_seeds(seed: Seed, n: int, bits: Literal[32, 64] = 32) -> NDArray[np.uint64]:
    """Seeds of ``n`` independent child streams of ``seed``, shape (n,).

    Child i's seed is the first word (``bits`` wide) of ``SeedSequence(seed).spawn(n)[i]``, so
    seed i does not depend on ``n``.
    """
    dtype = np.uint32 if bits == 32 else np.uint64
    children = np.random.SeedSequence(seed).spawn(n)
    return np.array([c.generate_state(1, dtype)[0] for c in children], dtype=np.uint64)


def draw_seeds(seed: Seed, n: int) -> list[int]:
    """``n`` seeds drawn as consecutive 32-bit words of ``SeedSequence(seed)``."""
    return [int(word) for word in np.random.SeedSequence(seed).generate_state(n)]
