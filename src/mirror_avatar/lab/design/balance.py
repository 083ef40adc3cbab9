"""How balanced a protocol's design is over its first N participants, before anyone comes.

For each block: how often each condition comes at each position of the order, how often the
person and the avatar fill the ``person-or-avatar`` slots at each position, and how often each
such slot is the person or the avatar (`block_balance`). A block is balanced when every
condition comes equally often at every position, each kind equally often at every position and
every slot meets each kind equally often; `problems` says what is not, and `balancing_count`
finds the next number of participants that balances every block.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.lab.design.order import design_rows
from mirror_avatar.lab.design.protocol import Protocol, Step

KINDS = ("person", "avatar")
"""The partner kinds counted, in the tables' order."""


@dataclass(frozen=True)
class BlockBalance:
    """Counts of one block's design over participants 0 .. N-1.

    Attributes
    ----------
    name
        The block's name.
    order
        Its order of conditions (`mirror_avatar.lab.design.order.ORDERS`).
    conditions
        Its conditions' names, in the file's order.
    positions
        Times each condition came at each position, shape (conditions, positions).
    kinds
        Times the person (row 0) and the avatar (row 1) filled a ``person-or-avatar`` slot at
        each position, shape (2, positions).
    slots
        Per ``person-or-avatar`` slot, named ``condition label``: times the person and the avatar
        filled it.
    """

    name: str
    order: str
    conditions: tuple[str, ...]
    positions: NDArray[np.int64]
    kinds: NDArray[np.int64]
    slots: dict[str, tuple[int, int]]

    def problems(self) -> list[str]:
        """Return what is not balanced, one phrase each (empty when the block is balanced)."""
        found = []
        if len(self.conditions) > 1 and np.ptp(self.positions) > 0:
            found.append(f"block '{self.name}': conditions not equally often at every position")
        if np.any(self.kinds[0] != self.kinds[1]):
            found.append(f"block '{self.name}': partner kinds not equally often at every position")
        uneven = [slot for slot, (person, avatar) in self.slots.items() if person != avatar]
        if uneven:
            found.append(f"block '{self.name}': {', '.join(uneven)} not as often each kind")
        return found


def block_balance(protocol: Protocol, schedules: list[list[Step]]) -> list[BlockBalance]:
    """Count each block's design over the participants' schedules (`Protocol.schedule`)."""
    balances = []
    for b, block in enumerate(protocol.blocks):
        n = len(block.conditions)
        positions = np.zeros((n, n), np.int64)
        kinds = np.zeros((2, n), np.int64)
        slots = {
            f"{condition.name} {player.label}": (0, 0)
            for condition in block.conditions
            for player in condition.players
            if player.kind == "person-or-avatar"
        }
        for steps in schedules:
            mine = [step for step in steps if step.block == b]
            for position, step in enumerate(mine):
                positions[step.condition, position] += 1
                for label, person in step.persons.items():
                    kinds[0 if person else 1, position] += 1
                    slot = f"{step.name} {label}"
                    count = slots[slot]
                    slots[slot] = (count[0] + person, count[1] + (not person))
        names = tuple(condition.name for condition in block.conditions)
        balances.append(BlockBalance(block.name, block.order, names, positions, kinds, slots))
    return balances


def balancing_count(protocol: Protocol, participants: int, most: int) -> int | None:
    """Return the fewest participants, more than ``participants``, that balance every block.

    None when no number up to ``most`` does.

    Only multiples of every block's cycle (twice its design's rows, `design_rows`) are tried:
    other counts leave a cycle of the crossed squares unfinished.
    """
    cycle = math.lcm(
        *(2 * design_rows(block.order, len(block.conditions)) for block in protocol.blocks)
    )
    first = (participants // cycle + 1) * cycle
    schedules = [protocol.schedule(p) for p in range(participants)]
    for count in range(first, most + 1, cycle):
        schedules += [protocol.schedule(p) for p in range(len(schedules), count)]
        if not any(block.problems() for block in block_balance(protocol, schedules)):
            return count
    return None
