"""``mirror-avatar lab preview``: a protocol's orders, partner kinds and balance, in advance."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from mirror_avatar.common.text import printable

if TYPE_CHECKING:
    from mirror_avatar.lab.design.balance import BlockBalance
    from mirror_avatar.lab.design.protocol import Protocol, Step

MAX_PREVIEW = 1000
"""Most participants previewed (participant numbers go up to 999)."""


@click.command()
@click.option(
    "--protocol",
    "protocol_file",
    required=True,
    type=click.Path(path_type=Path),
    help="The study protocol (TOML, the lab guide's 'Study protocols').",
)
@click.option(
    "--participants",
    type=click.IntRange(1, MAX_PREVIEW),
    default=8,
    show_default=True,
    help="How many participants to preview (numbers 0 to N-1, in the order sessions are run).",
)
def preview(protocol_file: Path, participants: int) -> None:
    """Print each participant's order of conditions and partner kinds, and how balanced they are.

    One line per participant: each block's conditions in that participant's order, with who
    fills each person-or-avatar slot. Then per block a table: how often each condition comes at
    each position, and the person and the avatar at each position; and a last line saying
    whether every block is balanced, or what is not and how many participants would balance it.
    Nothing is written: the lab draws the same orders and partners from the protocol's seed.
    """
    from mirror_avatar.lab.design.balance import block_balance
    from mirror_avatar.lab.design.protocol import load_protocol

    protocol = load_protocol(protocol_file)
    schedules = [protocol.schedule(p) for p in range(participants)]
    lines = [
        f"protocol {protocol_file}: {protocol.title!r}, seed {protocol.seed}, "
        f"{participants} participant(s)",
        "",
        *(f"p{p:03d}  {_order_line(protocol, steps)}" for p, steps in enumerate(schedules)),
    ]
    if protocol.seed_drawn:
        _show(
            f"warning: {protocol_file} has no seed: these draws are seed {protocol.seed}'s; add "
            f"'seed = {protocol.seed}' to the protocol for the lab to draw the same",
            err=True,
        )
    balances = block_balance(protocol, schedules)
    for balance in balances:
        lines += ["", *_table(balance)]
    lines += ["", _verdict(protocol, participants, balances)]
    for line in lines:
        _show(line)


def _show(line: str, err: bool = False) -> None:
    """Print a line with its control characters escaped: a name may not act on the terminal."""
    click.echo(printable(line), err=err)


def _verdict(protocol: Protocol, participants: int, balances: list[BlockBalance]) -> str:
    """Say whether every block is balanced, or what is not and what would balance it."""
    problems = [problem for balance in balances for problem in balance.problems()]
    if not problems:
        return (
            "balanced: every condition at every position equally often, each partner kind at "
            "each position equally often, each person-or-avatar slot as often each kind"
        )
    return f"not balanced: {'; '.join(problems)} ({_fix(protocol, participants, balances)})"


def _fix(protocol: Protocol, participants: int, balances: list[BlockBalance]) -> str:
    """Say what would balance every block: a counterbalanced order, or more participants."""
    from mirror_avatar.lab.design.balance import balancing_count

    unsquared = [
        f"'{balance.name}'"
        for balance in balances
        if balance.problems() and balance.order in ("fixed", "random")
    ]
    if unsquared:
        return (
            f"block {', '.join(unsquared)} is not counterbalanced: "
            'order = "latin" or "williams" balances it'
        )
    count = balancing_count(protocol, participants, MAX_PREVIEW)
    if count is None:
        return f"no number of participants up to {MAX_PREVIEW} balances every block"
    return f"{count} participants balance every block"


def _order_line(protocol: Protocol, steps: list[Step]) -> str:
    """Return a participant's order: each block's conditions, with the partner kinds drawn."""
    blocks: dict[int, list[str]] = {}
    for step in steps:
        kinds = ", ".join(
            f"{label} {'person' if person else 'avatar'}" for label, person in step.persons.items()
        )
        blocks.setdefault(step.block, []).append(f"{step.name} ({kinds})" if kinds else step.name)
    return " | ".join(
        f"{protocol.blocks[b].name}: {', '.join(names)}" for b, names in blocks.items()
    )


def _table(balance: BlockBalance) -> list[str]:
    """Return a block's balance table: times at each position of each condition and kind."""
    from mirror_avatar.lab.design.balance import KINDS

    names = list(balance.conditions) + [f"partner {kind}" for kind in KINDS]
    width = max(len(name) for name in names)
    n = len(balance.conditions)
    lines = [
        f"block '{balance.name}' ({balance.order}, {n} condition(s)): times at each position",
        f"  {'position':<{width}}" + "".join(f"{j + 1:>5}" for j in range(n)),
    ]
    rows = list(zip(names, [*balance.positions, *balance.kinds], strict=True))
    lines += [f"  {name:<{width}}" + "".join(f"{c:>5}" for c in counts) for name, counts in rows]
    if balance.slots:
        slots = "; ".join(
            f"{slot}: person {person}, avatar {avatar}"
            for slot, (person, avatar) in balance.slots.items()
        )
        lines.append(f"  person-or-avatar slots: {slots}")
    return lines
