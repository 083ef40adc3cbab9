"""``mirror-avatar lab pilot``: a study protocol played by virtual participants."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import click

from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import entropy_of

DEFAULT_STAND_IN = "bundled:slow"
"""The SPEC standing in for a person no --stand-in names."""


def _pairs(values: tuple[str, ...], option: str) -> dict[str, str]:
    """Read ``KEY=VALUE`` options into a mapping (one line naming the option otherwise)."""
    pairs = {}
    for value in values:
        key, sep, rest = value.partition("=")
        if not sep or not key or not rest:
            raise InputError(option, f"{value!r}: give KEY=VALUE, such as P1=bundled:slow")
        pairs[key] = rest
    return pairs


@click.command()
@click.option(
    "--protocol",
    "protocol_file",
    required=True,
    type=click.Path(path_type=Path),
    help="The study protocol (TOML) to pilot.",
)
@click.option(
    "--participants",
    type=click.IntRange(1, 1000),
    default=2,
    show_default=True,
    help="How many participants' runs to play.",
)
@click.option(
    "--at-once",
    type=click.IntRange(1, 16),
    default=1,
    show_default=True,
    help="How many participants' runs play at the same time against the one server, each "
    "starting as one ends (1: in turn). Each participant's stand-ins and seeds are the same "
    "however many play at once; only the timing differs.",
)
@click.option(
    "--first",
    type=click.IntRange(0, 10_000),
    default=0,
    show_default=True,
    help="The first participant's number (their row of the order).",
)
@click.option(
    "--stand-in",
    "stand_in",
    multiple=True,
    metavar="LABEL=SPEC",
    help=f"The player SPEC standing in for the person LABEL (repeatable; default "
    f"{DEFAULT_STAND_IN} for every person).",
)
@click.option(
    "--answer",
    multiple=True,
    metavar="QUESTION=RULE",
    help="How the virtual participants answer a question: random (default), first, "
    "value:TEXT, or detect:P for a person-or-computer question (the partners' true kind named "
    "with probability P) (repeatable).",
)
@click.option(
    "--seed",
    type=click.IntRange(0),
    default=None,
    help="The pilot's seed (the stand-ins' own seeds; default: drawn and printed).",
)
@click.option(
    "--network",
    "network_spec",
    multiple=True,
    metavar="[LABEL=]SPEC",
    help="Put an emulated internet between the virtual participants' pages and the server: "
    "one-way delay in ms and stalls, such as 80+-25 or 120+-40,stall=5:1 (its truth in "
    "OUT/pilot-network.csv). LABEL=SPEC puts person LABEL's page behind one of its own "
    "(its truth in OUT/pilot-network-LABEL.csv), such as --network P1=20+-5 --network "
    "P2=150+-40; repeatable, once per person.",
)
@click.option(
    "--out",
    "out_dir",
    required=True,
    type=click.Path(path_type=Path),
    help="Where the lab server records the runs (one folder per participant).",
)
def pilot(
    protocol_file: Path,
    participants: int,
    at_once: int,
    first: int,
    stand_in: tuple[str, ...],
    answer: tuple[str, ...],
    seed: int | None,
    network_spec: tuple[str, ...],
    out_dir: Path,
) -> None:
    """Play a protocol with virtual participants through the real lab server.

    Starts `mirror-avatar lab --protocol` on loopback and plays each participant's run in
    turn (or --at-once N at a time), in real time: every person's slot is joined by a virtual
    participant's page that sees what a person's page sees (partners delayed and hidden as the
    condition says) and moves a player SPEC on it, and answers the questions by rule. The
    folders are a real study's, so `mirror-avatar study table` and `study report` run on them
    before the first person comes.
    With --network, the pages reach the server through an emulated internet, as participants
    at home would (see `mirror-avatar lab proxy`), one for all or one per person.
    """
    from mirror_avatar.lab.design.protocol import load_protocol
    from mirror_avatar.lab.running.pilot import run_pilot
    from mirror_avatar.lab.running.pilot_network import describe, network_files, parse_networks
    from mirror_avatar.lab.running.stand_in_answers import AnswerRule

    protocol = load_protocol(protocol_file)
    given = _pairs(stand_in, "--stand-in")
    stand_ins = {label: given.get(label, DEFAULT_STAND_IN) for label in protocol.people} | given
    rules = {q: AnswerRule.parse(rule) for q, rule in _pairs(answer, "--answer").items()}
    networks = parse_networks(network_spec, protocol.people)
    check_output_dir(out_dir, files=network_files(networks))
    seed = entropy_of(seed)
    people = ", ".join(f"{label}={spec}" for label, spec in stand_ins.items())
    click.echo(
        f"pilot of {protocol_file}: participants {first}-{first + participants - 1}, "
        f"stand-ins {people}, seed {seed}"
        + (f", {at_once} at once" if at_once > 1 else "")
        + (f"; {describe(networks)}" if networks else "")
    )
    started = time.monotonic()

    def done(number: int, status: dict[str, Any]) -> None:
        trials = status.get("trials", [])
        cut = [f"trial {t['n']}: {t['end_reason']}" for t in trials if not t["complete"]]
        click.echo(
            f"participant {number}: {status['state']}, {len(trials) - len(cut)} of "
            f"{len(trials)} trial(s) complete ({time.monotonic() - started:.0f} s into the pilot)"
            + (f"; {'; '.join(cut)}" if cut else "")
        )

    run_pilot(
        protocol_file,
        out_dir,
        range(first, first + participants),
        stand_ins,
        seed,
        rules,
        done,
        networks,
        at_once,
    )
    click.echo(
        f"recorded in {out_dir.resolve()}; next: mirror-avatar study table {out_dir} --out RESULTS"
    )
