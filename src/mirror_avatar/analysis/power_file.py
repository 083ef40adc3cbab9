"""A power analysis written and read back: ``power.csv``, ``power.json`` and ``power.png``.

``power.csv`` has a row per number of participants (the hypothesis's power, its Monte Carlo
standard error and Wilson interval, and each primary measure's own power); ``power.json`` holds
the same with every input (the protocol's hypothesis, the planned effect, the pilot's spread,
the seed and the number of simulations, the table's file and SHA-256) and the smallest number
of participants reaching the target; ``power.png`` is the power curve
(`mirror_avatar.analysis.study_figures.plot_power`). `read_power` gives ``power.json`` back to
the registered plan (`mirror_avatar.analysis.plan`). The identification test's power
(`IdentificationPower`) is written in the same three files, its inputs the planned rate of right
answers and the pilot's persons' rates.
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pandas as pd

from mirror_avatar.analysis.identification import CHANCE
from mirror_avatar.analysis.identification_power import RateSpread
from mirror_avatar.analysis.power import INTERVAL, PowerPoint, Spread, smallest_participants
from mirror_avatar.analysis.study_figures import plot_power
from mirror_avatar.analysis.study_text import ALPHA
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import csv_text, json_text, write_atomic_files
from mirror_avatar.files.trial_io import MAX_SIDECAR_BYTES
from mirror_avatar.files.user_files import parse_json, read_text
from mirror_avatar.lab.design.protocol import Analysis
from mirror_avatar.report import render_png

POWER_FILES = ("power.csv", "power.json", "power.png")
"""The files `write_power` writes in its folder."""

IDENTIFICATION_TEST = (
    "persons' rates of right answers against 0.5, two-sided one-sample t-test over persons "
    "(the pooled exact binomial when fewer than two persons' rates differ), counted on the "
    "planned side of chance"
)
"""The identification test whose power is simulated, in words."""

EITHER_SIDE = "either_side"
"""The name of the identification test's power on either side of chance (``power_either_side``)."""


class SimulatedPower(Protocol):
    """What `write_power` writes: a row per number of participants, and every input."""

    @property
    def target(self) -> float:
        """The power aimed at."""

    @property
    def smallest(self) -> int | None:
        """The smallest number of participants reaching the target."""

    def frame(self) -> pd.DataFrame:
        """Return a row per number of participants, for ``power.csv``."""

    def to_json(self) -> dict[str, Any]:
        """Every input and result, for ``power.json``."""


@dataclass(frozen=True)
class PowerAnalysis:
    """A power analysis: its inputs and the simulated power at each number of participants.

    Parameters
    ----------
    analysis
        The protocol's declared hypothesis.
    spread
        The pilot's spread of the paired differences.
    effect
        The planned effect, in the primary measures' units, in the declared direction.
    target
        The power aimed at (a share, 0 to 1).
    seed
        The simulations' seed.
    points
        The power at each number of participants simulated, in increasing order.
    table, protocol
        The pilot's table and the protocol, as files.
    trials
        The planned trials per condition, None for the pilot's.
    """

    analysis: Analysis
    spread: Spread
    effect: float
    target: float
    seed: int
    points: list[PowerPoint]
    table: Path
    protocol: Path
    trials: int | None = None

    @property
    def smallest(self) -> int | None:
        """The smallest number of participants reaching the target (`smallest_participants`)."""
        return smallest_participants(self.points, self.target)

    def frame(self) -> pd.DataFrame:
        """Return a row per number of participants, for ``power.csv``."""
        return pd.DataFrame([_row(point, self.spread.measures) for point in self.points])

    def to_json(self) -> dict[str, Any]:
        """Every input and result, for ``power.json``."""
        sd = self.spread.sd
        return _inputs(self.table, self.protocol) | {
            "hypothesis": asdict(self.analysis), "effect": self.effect,
            "standardised_effect": dict(zip(self.spread.measures, self.effect / sd, strict=True)),
            "pilot": {
                "participants": self.spread.participants,
                "sd_of_differences": dict(zip(self.spread.measures, sd, strict=True)),
                "covariance": self.spread.covariance.tolist(),
                "trial_covariance": self.spread.trial_covariance.tolist(),
                "trial_factor": self.spread.trial_factor,
                "mean_differences": dict(zip(self.spread.measures,
                                             self.spread.pilot_differences, strict=True)),
            },
            "trials_per_condition": self.trials,
        } | _results(self.frame(), self.target, self.seed, self.smallest)  # fmt: skip


@dataclass(frozen=True)
class IdentificationPower:
    """The identification test's power: its inputs and the power at each number of persons.

    Parameters
    ----------
    spread
        The pilot's persons' rates of right answers.
    rate
        The planned mean rate of right answers (a share, 0 to 1).
    answers
        Each simulated person's answers.
    target, seed, points, table, protocol
        As `PowerAnalysis`'s (``points``: per number of persons).
    """

    spread: RateSpread
    rate: float
    answers: int
    target: float
    seed: int
    points: list[PowerPoint]
    table: Path
    protocol: Path

    @property
    def smallest(self) -> int | None:
        """The smallest number of persons reaching the target (`smallest_participants`)."""
        return smallest_participants(self.points, self.target)

    def frame(self) -> pd.DataFrame:
        """Return a row per number of persons, for ``power.csv``."""
        return pd.DataFrame([_row(point, (EITHER_SIDE,)) for point in self.points])

    def to_json(self) -> dict[str, Any]:
        """Every input and result, for ``power.json``."""
        return _inputs(self.table, self.protocol) | {
            "hypothesis": {"test": "identification", "model": IDENTIFICATION_TEST,
                           "chance": CHANCE, "alpha": ALPHA},
            "rate": self.rate, "pilot": self.spread.to_json(),
            "answers_per_person": self.answers,
        } | _results(self.frame(), self.target, self.seed, self.smallest)  # fmt: skip


def _inputs(table: Path, protocol: Path) -> dict[str, Any]:
    return {"protocol": protocol.name, "table": table.name, "table_sha256": file_sha256(table)}


def _results(frame: pd.DataFrame, target: float, seed: int, smallest: int | None) -> dict[str, Any]:
    return {
        "target": target, "seed": seed, "simulations": int(frame["simulations"].iloc[0]),
        "interval": f"Wilson {INTERVAL:.0%}", "power": frame.to_dict(orient="records"),
        "smallest_participants": smallest,
    }  # fmt: skip


def _row(point: PowerPoint, measures: tuple[str, ...]) -> dict[str, Any]:
    low, high = point.interval
    own = {f"power_{m}": r / point.simulations for m, r in zip(measures, point.rejections,
                                                               strict=True)}  # fmt: skip
    return {
        "participants": point.participants, "simulations": point.simulations,
        "rejections": point.all_rejections, "power": point.power,
        "mc_se": point.standard_error, "ci_low": low, "ci_high": high,
    } | own  # fmt: skip


def file_sha256(path: Path) -> str:
    """Return the hex SHA-256 of a file's bytes."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def write_power(power: SimulatedPower, out_dir: Path) -> None:
    """Write `POWER_FILES` in ``out_dir`` (created if missing), all or none."""
    out_dir.mkdir(parents=True, exist_ok=True)
    table = power.frame()
    figure = plot_power(
        table["participants"].to_numpy(np.int64),
        table["power"].to_numpy(np.float64),
        table[["ci_low", "ci_high"]].to_numpy(np.float64),
        power.target,
    )
    csv, json_file, png = POWER_FILES
    contents: dict[str, str | bytes] = {
        csv: csv_text(table, index=False),
        json_file: json_text(power.to_json()),
        png: render_png(figure),
    }
    write_atomic_files(out_dir, contents)


def read_power(folder: Path) -> dict[str, Any]:
    """Read ``power.json`` from the folder `write_power` wrote (or the file itself).

    Raises
    ------
    InputError
        No ``power.json`` there, or one that is not a power analysis's.
    """
    file = folder / POWER_FILES[1] if folder.is_dir() else folder
    if not file.is_file():
        raise InputError(folder, "no power.json: give the folder `study power --out` wrote")
    found = parse_json(read_text(file, MAX_SIDECAR_BYTES), file)
    if not isinstance(found, dict) or not {"power", "hypothesis", "target"} <= found.keys():
        raise InputError(file, "is not a power analysis (`study power` writes power.json)")
    return found
