"""``mirror-avatar study power``: a test's power by simulation, from a pilot's table.

The test is the protocol's declared hypothesis, or, with ``--test identification``, the
report's test of the "person or computer?" answers against chance.
"""

from __future__ import annotations

from pathlib import Path

import click

from mirror_avatar.analysis.identification_power import (
    answers_per_person,
    pilot_rates,
    simulate_identification,
)
from mirror_avatar.analysis.power import PowerPoint, pilot_spread, simulate_power
from mirror_avatar.analysis.power_file import (
    POWER_FILES,
    IdentificationPower,
    PowerAnalysis,
    SimulatedPower,
    write_power,
)
from mirror_avatar.analysis.study_file import StudyTable, read_study_table
from mirror_avatar.cli.constrained import SEED, ranged
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.common.constraints import Interval
from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import Analysis, load_protocol

PARTICIPANTS = Interval(int, 2, 10_000)
"""A simulated study's participants."""

SIMULATIONS = Interval(int, 100, 1_000_000)
"""Simulated studies per number of participants."""

TARGET = Interval(float, 0.0, 1.0, "neither")
"""A power aimed at."""

EFFECT = Interval(float, 0.0, None, "neither")
"""A planned effect, in the primary measures' units."""

TRIALS = Interval(int, 1, 10_000)
"""Planned trials per condition."""

RATE = Interval(float, 0.0, 1.0, "neither")
"""A planned mean rate of right answers."""

TESTS = ("declared", "identification")
"""The tests whose power `power` simulates."""


@click.command()
@click.argument("table", type=click.Path(path_type=Path))
@click.option("--protocol", "protocol_file", type=click.Path(path_type=Path), required=True,
              help="The study's protocol: its [analysis] declares the test (with --test "
                   "identification, its questions after trials give the answers).")  # fmt: skip
@click.option("--test", "test", type=click.Choice(TESTS), default="declared", show_default=True,
              help="The protocol's declared hypothesis, or the identification test: the persons' "
                   "rates of right answers to \"person or computer?\" against chance.")  # fmt: skip
@click.option("--participants", default="6,8,12,16,24", show_default=True,
              help="The numbers of participants simulated, separated by commas.")  # fmt: skip
@click.option("--effect", default=None,
              **ranged("The planned effect in the primary measures' units, in the declared "
                       "direction [default: the protocol's smallest_effect].", EFFECT))  # fmt: skip
@click.option("--trials", default=None,
              **ranged("Planned trials per participant and condition [default: the pilot's]; "
                       "with --test identification, answers per person [default: the "
                       "protocol's].", TRIALS))  # fmt: skip
@click.option("--rate", default=None,
              **ranged("With --test identification: the planned mean rate of right answers "
                       "[default: the pilot's].", RATE))  # fmt: skip
@click.option("--target", default=0.8, show_default=True, **ranged("The power aimed at.", TARGET))
@click.option("--simulations", default=1000, show_default=True,
              **ranged("Simulated studies per number of participants.", SIMULATIONS))  # fmt: skip
@click.option("--seed", default=0, show_default=True, **ranged("Seed of the simulations.", SEED))
@click.option("--out", "out_dir", type=click.Path(path_type=Path), required=True,
              help="Folder for power.csv, power.json and power.png.")  # fmt: skip
def power(
    table: Path,
    protocol_file: Path,
    test: str,
    participants: str,
    effect: float | None,
    trials: int | None,
    rate: float | None,
    target: float,
    simulations: int,
    seed: int,
    out_dir: Path,
) -> None:
    """Simulate the power of a test at several numbers of participants.

    TABLE is a pilot's study table (a folder holding study.csv, or the table). Per primary
    measure, the spread of the participants' paired differences (condition minus reference)
    is estimated from it; studies of each number of participants are simulated with the
    planned effect and that spread (with --trials, the pilot's trial noise rescaled to that
    number of trials per condition), and tested as `study report` tests the hypothesis (paired
    t-test, one-sided as declared, Holm over the primary measures). Writes the power, its Monte
    Carlo standard error and 95 % Wilson interval per number (power.csv), every input with the
    table's SHA-256 and the smallest number reaching the target (power.json), and the power
    curve (power.png).

    With --test identification, the persons' rates of right answers to "person or computer?"
    are fitted as a logit-normal spread (a random intercept per person); studies of each number
    of persons, each answering as many times as the protocol asks (--trials: another number),
    are simulated around the planned mean rate (--rate, default the pilot's) and tested as
    `study report` tests them (the persons' rates against 0.5 by a two-sided t-test over
    persons); a study counts when it finds the planned side of chance.
    """
    sizes = _sizes(participants)
    check_output_dir(out_dir, files=POWER_FILES)
    study = read_study_table(table)
    if test == "identification":
        if effect is not None:
            raise InputError("--effect", "is the declared test's: give --rate for the "
                             "identification test")  # fmt: skip
        found: SimulatedPower = _identification(study, protocol_file, sizes, simulations, seed,
                                                 trials, rate, target)  # fmt: skip
    else:
        if rate is not None:
            raise InputError("--rate", "is the identification test's: give --test "
                             "identification, or --effect for the declared test")  # fmt: skip
        found = _declared_power(study, protocol_file, sizes, simulations, seed, effect, trials,
                                target)  # fmt: skip
    write_power(found, out_dir)
    smallest = found.smallest
    click.echo(
        f"power {target:g} reached from {smallest} participants"
        if smallest is not None
        else f"power {target:g} not reached with {sizes[-1]} participants"
    )
    click.echo(f"wrote {out_dir.resolve()}")


def _declared_power(
    study: StudyTable, protocol_file: Path, sizes: list[int], simulations: int, seed: int,
    effect: float | None, trials: int | None, target: float,
) -> PowerAnalysis:  # fmt: skip
    """Simulate the declared test's power at each number of participants."""
    analysis = _declared(protocol_file)
    spread = pilot_spread(study, analysis, str(protocol_file))
    points = [_said(simulate_power(spread, analysis, n, simulations, seed, effect, trials))
              for n in sizes]  # fmt: skip
    return PowerAnalysis(
        analysis=analysis, spread=spread,
        effect=analysis.smallest_effect if effect is None else effect, target=target,
        seed=seed, points=points, table=study.source, protocol=protocol_file, trials=trials,
    )  # fmt: skip


def _identification(
    study: StudyTable, protocol_file: Path, sizes: list[int], simulations: int, seed: int,
    trials: int | None, rate: float | None, target: float,
) -> IdentificationPower:  # fmt: skip
    """Simulate the identification test's power at each number of persons."""
    protocol = load_protocol(protocol_file)
    answers = answers_per_person(protocol) if trials is None else trials
    spread = pilot_rates(study)
    planned = spread.mean_rate if rate is None else rate
    points = [_said(simulate_identification(spread, n, answers, simulations, seed, planned))
              for n in sizes]  # fmt: skip
    return IdentificationPower(
        spread=spread, rate=planned, answers=answers, target=target, seed=seed, points=points,
        table=study.source, protocol=protocol_file,
    )  # fmt: skip


def _said(point: PowerPoint) -> PowerPoint:
    """Print a number's power on stderr; return it."""
    click.echo(f"{point.participants} participants: power {point.power:.3f} "
               f"({point.simulations} studies)", err=True)  # fmt: skip
    return point


def _sizes(text: str) -> list[int]:
    """Read ``--participants``: whole numbers in `PARTICIPANTS`, sorted, each once."""
    try:
        sizes = sorted({int(part) for part in text.split(",")})
    except ValueError:
        raise InputError(
            "--participants", f"{text!r} is not whole numbers separated by commas"
        ) from None
    if not all(n in PARTICIPANTS for n in sizes):
        raise InputError("--participants", "each number must be from 2 to 10000")
    return sizes


def _declared(protocol_file: Path) -> Analysis:
    """Return the protocol's declared hypothesis; refuse a protocol that declares none."""
    analysis = load_protocol(protocol_file).analysis
    if analysis is None:
        raise InputError(protocol_file, "no [analysis]: the power is that of the declared test")
    return analysis
