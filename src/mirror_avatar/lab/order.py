"""The order in which a participant meets a block's conditions: fixed, random or counterbalanced.

Counterbalancing follows the designs of crossover experiments (Williams 1949, "Experimental
designs balanced for the estimation of residual effects of treatments", Aust. J. Sci. Res. A
2:149-168):

- ``latin``: a cyclic Latin square, row ``i`` = ``(i, i+1, ..., i+n-1) mod n``; each condition
  comes once in every row (participant) and once in every column (position).
- ``williams``: a Latin square in which each condition also immediately precedes every other
  equally often (n rows for an even n; for an odd n the n rows and their reverses, 2n rows).

Participant ``p`` (0, 1, 2, ... in the order sessions are run) takes row ``p mod rows``. The
conditions are assigned to the square's symbols by a permutation drawn from the protocol's seed
(the same for every participant, so the balance holds); ``random`` draws each participant's
order from the seed and the participant's number. Every order is therefore reproduced from the
recorded seed.
"""

from __future__ import annotations

import numpy as np

ORDERS = ("fixed", "random", "latin", "williams")
"""Ways of ordering a block's conditions."""


def latin_square(n: int) -> list[list[int]]:
    """Return the cyclic Latin square of order ``n``: n rows, each a permutation of 0..n-1."""
    return [[(i + j) % n for j in range(n)] for i in range(n)]


def williams_square(n: int) -> list[list[int]]:
    """Return Williams' design of order ``n`` (n rows if n is even, 2n if odd).

    The first row is 0, 1, n-1, 2, n-2, ...; row i adds i to it (mod n). For an odd n the
    reversed rows are appended, which balances the immediate precedences.
    """
    first = [0 if j == 0 else (j + 1) // 2 if j % 2 else n - j // 2 for j in range(n)]
    rows = [[(c + i) % n for c in first] for i in range(n)]
    if n % 2:
        rows += [row[::-1] for row in rows]
    return rows


def condition_order(method: str, n: int, participant: int, seed: int, block: int) -> list[int]:
    """Return the order (indices 0..n-1) in which a participant plays a block's n conditions.

    Parameters
    ----------
    method
        One of `ORDERS`.
    n
        Number of conditions in the block.
    participant
        The participant's number (0-based, in the order sessions are run).
    seed
        The protocol's seed.
    block
        The block's index (each block has its own draws).
    """
    if method == "fixed" or n == 1:
        return list(range(n))
    if method == "random":
        rng = np.random.default_rng([seed, 2, block, participant])
        return [int(k) for k in rng.permutation(n)]
    square = latin_square(n) if method == "latin" else williams_square(n)
    symbols = np.random.default_rng([seed, 3, block]).permutation(n)
    return [int(symbols[s]) for s in square[participant % len(square)]]


def block_order(method: str, n: int, participant: int, seed: int) -> list[int]:
    """Return the order of a protocol's n blocks for a participant (``fixed`` or ``random``)."""
    if method == "fixed" or n == 1:
        return list(range(n))
    rng = np.random.default_rng([seed, 1, participant])
    return [int(k) for k in rng.permutation(n)]
