"""Seeds: every random choice in the toolkit derives from one integer, in one of two ways.

A run seed is turned into the seeds of its parts by `spawn_seeds` (independent child streams of
`numpy.random.SeedSequence`, one per session or per player) or by `draw_seeds` (words drawn from
one stream, for a few fixed parts of a run). `entropy_of` returns the integer a ``None`` seed
actually used, so that it can be recorded and the run replayed.

`spawn_seeds` of an integer seed runs `numpy.random.SeedSequence`'s hashing (M. E. O'Neill's
``seed_seq`` alternative, as NumPy implements it) in compiled code, word for word, because the
batch engine spawns the seeds of every session and of its players: NumPy builds an object per
child. Other seeds go through NumPy itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
from numba import njit
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
    if isinstance(seed, int | np.integer) and seed >= 0:
        return _spawn_words(_uint32_words(int(seed)), n, bits // 32)
    dtype = np.uint32 if bits == 32 else np.uint64
    children = np.random.SeedSequence(seed).spawn(n)
    return np.array([c.generate_state(1, dtype)[0] for c in children], dtype=np.uint64)


POOL_SIZE = 4
"""Words of `numpy.random.SeedSequence`'s entropy pool (its default)."""
_MASK = 0xFFFFFFFF
_INIT_A, _MULT_A, _INIT_B, _MULT_B = 0x43B0D7E5, 0x931E8875, 0x8B51F9DD, 0x58F38DED
_MIX_MULT_L, _MIX_MULT_R = 0xCA01F9DD, 0x4973F715


def _uint32_words(value: int) -> NDArray[np.int64]:
    """Split a non-negative integer into 32-bit words, lowest first (0: one word), as NumPy does."""
    words = [value & _MASK]
    while value > _MASK:
        value >>= 32
        words.append(value & _MASK)
    return np.array(words, dtype=np.int64)


@njit(cache=True, nogil=True)
def _hashmix(value: int, hash_const: int) -> tuple[int, int]:
    """Return the hashed word and the next hash constant.

    Words are 32-bit values held in int64: products wrap modulo 2^64 and are masked to their
    low 32 bits, which is NumPy's uint32 arithmetic.
    """
    value ^= hash_const
    hash_const = (hash_const * _MULT_A) & _MASK
    value = (value * hash_const) & _MASK
    return value ^ (value >> 16), hash_const


@njit(cache=True, nogil=True)
def _mix(x: int, y: int) -> int:
    result = (_MIX_MULT_L * x - _MIX_MULT_R * y) & _MASK
    return result ^ (result >> 16)


@njit(cache=True, nogil=True)
def _spawn_words(entropy: NDArray[np.int64], n: int, n_words: int) -> NDArray[np.uint64]:
    """First ``n_words`` words (1 or 2, joined into one integer) of children 0 .. n - 1.

    Child i has the spawn key (i,): its entropy is ``entropy`` (32-bit words) padded with zeros
    to the pool size, then i; it is mixed into the pool and the state generated as NumPy does.
    """
    length = max(entropy.size, POOL_SIZE)
    assembled = np.zeros(length + 1, np.int64)
    assembled[: entropy.size] = entropy
    pool = np.empty(POOL_SIZE, np.int64)
    seeds = np.empty(n, np.int64)
    for child in range(n):
        assembled[length] = child
        hash_const = _INIT_A
        for i in range(POOL_SIZE):
            pool[i], hash_const = _hashmix(assembled[i], hash_const)
        for source in range(POOL_SIZE):
            for target in range(POOL_SIZE):
                if source != target:
                    word, hash_const = _hashmix(pool[source], hash_const)
                    pool[target] = _mix(pool[target], word)
        for source in range(POOL_SIZE, length + 1):
            for target in range(POOL_SIZE):
                word, hash_const = _hashmix(assembled[source], hash_const)
                pool[target] = _mix(pool[target], word)
        seed, hash_const = 0, _INIT_B
        for w in range(n_words):
            value = pool[w] ^ hash_const
            hash_const = (hash_const * _MULT_B) & _MASK
            value = (value * hash_const) & _MASK
            seed |= (value ^ (value >> 16)) << (32 * w)
        seeds[child] = seed
    return seeds.view(np.uint64)


def draw_seeds(seed: Seed, n: int) -> list[int]:
    """``n`` seeds drawn as consecutive 32-bit words of ``SeedSequence(seed)``."""
    return [int(word) for word in np.random.SeedSequence(seed).generate_state(n)]
