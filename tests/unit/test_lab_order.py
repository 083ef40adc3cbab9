"""Orders of a block's conditions: Latin squares, Williams designs, random and fixed orders."""

from __future__ import annotations

import itertools
from collections import Counter

import pytest

from mirror_avatar.lab.design.order import (
    block_order,
    condition_order,
    latin_square,
    williams_square,
)


def _is_latin(rows: list[list[int]], n: int) -> bool:
    every = set(range(n))
    return all(set(row) == every for row in rows) and all(
        set(column) == every for column in zip(*rows, strict=True)
    )


@pytest.mark.parametrize("n", range(1, 9))
def test_latin_square_has_each_condition_once_per_row_and_column(n):
    rows = latin_square(n)
    assert len(rows) == n
    assert _is_latin(rows, n)


@pytest.mark.parametrize("n", range(2, 10))
def test_williams_square_balances_immediate_precedence(n):
    rows = williams_square(n)
    assert len(rows) == (n if n % 2 == 0 else 2 * n)
    assert _is_latin(rows[:n], n)
    if n % 2:
        assert _is_latin(rows[n:], n)
    pairs = Counter((a, b) for row in rows for a, b in itertools.pairwise(row))
    expected = 1 if n % 2 == 0 else 2
    assert set(pairs) == {(a, b) for a in range(n) for b in range(n) if a != b}
    assert set(pairs.values()) == {expected}


def test_williams_square_of_four_is_the_textbook_one():
    assert williams_square(4) == [[0, 1, 3, 2], [1, 2, 0, 3], [2, 3, 1, 0], [3, 0, 2, 1]]


@pytest.mark.parametrize("method", ["latin", "williams"])
def test_counterbalanced_orders_across_participants_keep_the_balance(method):
    n = 4
    orders = [condition_order(method, n, p, seed=11, block=1) for p in range(n)]
    assert _is_latin(orders, n)
    assert condition_order(method, n, n, seed=11, block=1) == orders[0]
    if method == "williams":
        pairs = Counter((a, b) for row in orders for a, b in itertools.pairwise(row))
        assert set(pairs.values()) == {1} and len(pairs) == n * (n - 1)


def test_orders_are_reproduced_from_the_seed_and_differ_by_seed():
    first = [condition_order("random", 5, p, seed=3, block=0) for p in range(6)]
    assert first == [condition_order("random", 5, p, seed=3, block=0) for p in range(6)]
    assert all(sorted(order) == list(range(5)) for order in first)
    assert len({tuple(order) for order in first}) > 1
    other = [condition_order("random", 5, p, seed=4, block=0) for p in range(6)]
    assert other != first
    assert condition_order("fixed", 3, 5, seed=3, block=0) == [0, 1, 2]


def test_block_orders_are_permutations_from_the_seed():
    orders = [block_order("random", 3, p, seed=9) for p in range(8)]
    assert all(sorted(order) == [0, 1, 2] for order in orders)
    assert len({tuple(order) for order in orders}) > 1
    assert block_order("fixed", 3, 2, seed=9) == [0, 1, 2]
