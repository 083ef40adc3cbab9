"""Designs without confounds: conditions and partner kinds balanced over the positions of the order
and over participants, counted as `lab preview` counts them."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from mirror_avatar.lab.design.balance import balancing_count, block_balance
from mirror_avatar.lab.design.order import design_rows
from mirror_avatar.lab.design.protocol import Protocol, parse_protocol

SEEDS = (0, 7, 20261125, 99991)


def _protocol(n: int, order: str, seed: int, solo: int = 0) -> Protocol:
    """A block of ``n`` joint conditions with a person-or-avatar partner, then ``solo`` solos."""
    conditions = [
        {
            "name": f"c{c}",
            "game": "joint",
            "players": [
                {"label": "P1", "kind": "person"},
                {"label": "P2", "kind": "person-or-avatar", "spec": "bundled:slow"},
            ],
        }
        for c in range(n)
    ] + [
        {"name": f"s{c}", "game": "solo", "players": [{"label": "P1", "kind": "person"}]}
        for c in range(solo)
    ]
    data = {"seed": seed, "blocks": [{"name": "b", "order": order, "conditions": conditions}]}
    return parse_protocol(data, "design.toml")


def _counts(protocol: Protocol, participants: int):
    schedules = [protocol.schedule(p) for p in range(participants)]
    return schedules, block_balance(protocol, schedules)[0]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize(
    ("n", "order"), [(2, "latin"), (2, "williams"), (4, "latin"), (4, "williams")]
)
def test_eight_participants_balance_conditions_and_kinds_at_every_position(n, order, seed):
    schedules, balance = _counts(_protocol(n, order, seed), 8)
    assert set(balance.positions.ravel()) == {8 // n}
    assert (balance.kinds == 4).all()  # every participant meets a slot at every position
    assert balance.slots == {f"c{c} P2": (4, 4) for c in range(n)}
    assert balance.problems() == []
    cells = Counter(
        (step.condition, j, step.persons["P2"])
        for steps in schedules
        for j, step in enumerate(steps)
    )  # the two squares crossed: each condition meets each kind at each position
    assert set(cells.values()) == {8 // (2 * n)} and len(cells) == 2 * n * n


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("order", ["latin", "williams"])
def test_three_conditions_balance_over_whole_cycles_of_the_crossed_squares(order, seed):
    protocol = _protocol(3, order, seed)
    cycle = 2 * design_rows(order, 3)  # latin: 3 rows, williams: 6
    for participants in (cycle, 2 * cycle):
        _, balance = _counts(protocol, participants)
        assert balance.problems() == [], participants
        assert set(balance.kinds.ravel()) == {participants // 2}
        assert set(balance.positions.ravel()) == {participants // 3}
    _, balance = _counts(protocol, 8)  # 8 participants cannot share 3 positions evenly
    problems = balance.problems()
    assert problems[0] == "block 'b': conditions not equally often at every position"
    assert not any("kinds not equally often" in problem for problem in problems)
    assert (balance.kinds == 4).all()
    assert balancing_count(protocol, 8, 1000) == 12


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize(
    ("n", "order"), [(2, "fixed"), (3, "random"), (3, "latin"), (4, "williams"), (5, "williams")]
)
def test_every_pair_of_participants_meets_each_kind_at_each_position(n, order, seed):
    schedules, _ = _counts(_protocol(n, order, seed), 12)
    for first, second in zip(schedules[::2], schedules[1::2], strict=True):
        for a, b in zip(first, second, strict=True):
            assert a.persons["P2"] != b.persons["P2"]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("order", ["latin", "williams"])
def test_a_block_with_conditions_without_a_slot_balances_over_whole_cycles(order, seed):
    protocol = _protocol(3, order, seed, solo=1)  # 4 conditions, 3 with a slot: 8 a cycle
    for participants in (8, 16):
        _, balance = _counts(protocol, participants)
        assert balance.problems() == [], participants
        assert set(balance.kinds.ravel()) == {participants * 3 // 8}


@pytest.mark.parametrize("seed", SEEDS)
def test_a_participant_meets_both_kinds_in_a_block_of_two_or_more(seed):
    schedules, _ = _counts(_protocol(4, "williams", seed), 8)
    assert all({step.persons["P2"] for step in steps} == {True, False} for steps in schedules)


def test_the_draws_depend_on_the_seed():
    firsts = {_protocol(2, "latin", seed).schedule(0)[0].persons["P2"] for seed in range(20)}
    assert firsts == {True, False}
    orders = {
        tuple(s.condition for s in _protocol(4, "latin", seed).schedule(0)) for seed in range(20)
    }
    assert len(orders) > 1


def test_a_fixed_order_of_several_conditions_is_never_balanced():
    protocol = _protocol(2, "fixed", 3)
    _, balance = _counts(protocol, 8)
    assert balance.problems() == ["block 'b': conditions not equally often at every position"]
    assert np.array_equal(balance.kinds, [[4, 4], [4, 4]])
    assert balancing_count(protocol, 8, 40) is None
