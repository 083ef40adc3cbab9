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

Who fills a ``person-or-avatar`` slot (`meets_person`) is balanced over the positions of the
order as well as over participants: the partner kinds form a second square crossed with the
first (see `meets_person`), so that neither the order nor the participant is confounded with
the partner's kind.

Every draw derives from the protocol's seed through `mirror_avatar.common.seeds`
(`design_generator`).
"""

from __future__ import annotations

import numpy as np

from mirror_avatar.common.seeds import draw_seeds, spawn_seeds

ORDERS = ("fixed", "random", "latin", "williams")
"""Ways of ordering a block's conditions."""

DRAWS = ("block order", "symbols", "random order", "partners")
"""The design's draws, each its own stream of the protocol's seed (`design_generator`)."""


def design_generator(seed: int, draw: str, *path: int) -> np.random.Generator:
    """Return the generator of one of the design's `DRAWS` at ``path`` (block, participant, ...).

    The draw's seed is one word of the protocol seed's stream
    (`mirror_avatar.common.seeds.draw_seeds`, one word per draw); each index of ``path`` then takes
    that child stream (`mirror_avatar.common.seeds.spawn_seeds`), so a block's or a participant's
    draws do not depend on
    how many blocks or participants there are.
    """
    word = draw_seeds(seed, len(DRAWS))[DRAWS.index(draw)]
    for index in path:
        word = int(spawn_seeds(word, index + 1)[index])
    return np.random.default_rng(word)


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
        rng = design_generator(seed, "random order", block, participant)
        return [int(k) for k in rng.permutation(n)]
    square = latin_square(n) if method == "latin" else williams_square(n)
    symbols = design_generator(seed, "symbols", block).permutation(n)
    return [int(symbols[s]) for s in square[participant % len(square)]]


def design_rows(method: str, n: int) -> int:
    """Return the rows of a block's design: the square's (``latin``, ``williams``), else 1."""
    if method == "latin" and n > 1:
        return n
    if method == "williams" and n > 1:
        return n if n % 2 == 0 else 2 * n
    return 1


def meets_person(method: str, n: int, participant: int, position: int, first: bool) -> bool:
    """Whether the person (True) or the avatar fills a ``person-or-avatar`` slot.

    Parameters
    ----------
    method, n
        The block's order (`ORDERS`) and number of conditions.
    participant
        The participant's number (0-based).
    position
        The position (0-based) of the slot's condition in the participant's order of the block.
    first
        Whether participant 0 meets the person at the block's first position (drawn from the
        seed per block and slot label, `first_meets_person`).

    Notes
    -----
    **Choice**: a square of kinds crossed with the square of conditions. Participant ``p``
    takes row ``r = p mod R`` of the block's design (`design_rows`: R rows) in its cycle
    ``q = p // R``; the person fills the slot at position ``j`` when ``h(j) + r + q`` is even
    (odd when ``first`` is False), with ``h(j) = 1`` in the second half of the order
    (``2 j >= n``), else 0. Hence:

    - in each pair of participants (0 and 1, 2 and 3, ...) one meets the person and the other
      the avatar at every position where both meet such a slot, so each kind comes at each
      position equally often;
    - cycle ``q + 1`` repeats cycle ``q``'s rows with every kind swapped, so every ``2 R``
      participants each condition meets each kind at each position equally often (the two
      squares crossed), and each condition meets each kind equally often;
    - each participant meets one kind in the first half of its order and the other in the
      second: both kinds when the block's slots fall in both halves (always when each of its
      two or more conditions has one).

    Balancing each condition's kinds within every pair as well would leave each participant one
    kind only (for consecutive rows of a square the two demands have no other solution); the
    crossing balances the conditions' kinds over whole cycles instead.
    """
    rows = design_rows(method, n)
    row, cycle = participant % rows, participant // rows
    later = int(2 * position >= n)
    return (later + row + cycle + int(not first)) % 2 == 0


def first_meets_person(seed: int, block: int, slot: int) -> bool:
    """Draw whether participant 0 meets the person at a block's first position.

    ``slot`` numbers the slot's label (its index among the protocol's people).
    """
    return bool(design_generator(seed, "partners", block, slot).random() < 0.5)


def block_order(method: str, n: int, participant: int, seed: int) -> list[int]:
    """Return the order of a protocol's n blocks for a participant (``fixed`` or ``random``)."""
    if method == "fixed" or n == 1:
        return list(range(n))
    rng = design_generator(seed, "block order", participant)
    return [int(k) for k in rng.permutation(n)]
