"""Partners side by side following recorded leaders, as Zhai et al. (2017) compare them (Table 4).

Each chosen model follows each recorded leader (a `RecordedPlayer`) in the Python step loop; each
recorded human follower, when given, is scored against its leader the same way. Scores per
trial: RMS position error, relative position error (`relative_position_error`), CV (phase
locking of the relative phase), time lag, the normalised EMD between the follower's and the
leader's velocity distributions (`mirror_avatar.metrics.session_metrics`), and the largest
position and velocity errors. The first `TRIM` seconds are dropped: the partners start at rest.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from tqdm import tqdm

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.engine.loop import play
from mirror_avatar.errors import InputError
from mirror_avatar.metrics import session_metrics
from mirror_avatar.players import Player, RecordedPlayer
from mirror_avatar.players.dynamical import parse_options
from mirror_avatar.session import Session
from mirror_avatar.specs import MODEL_PARTNERS, load_player
from mirror_avatar.trials import Trial

Array = NDArray[np.float64]

TRIM = 1.0
"""Seconds dropped at the start of every trial before scoring (**choice**)."""

VIRTUAL_TRAINER_SPEC = "bundled:slow"
"""The optimal-control virtual trainer the benchmark calls ``vt`` (**choice**: a signature learnt
from the bundled slow trials, the follower preset)."""

MODELS = (*MODEL_PARTNERS, "vt")
"""The models the benchmark can run, by name."""

HUMAN = "human"
"""The row of the recorded human followers."""

PUBLISHED = {
    "rpe": {HUMAN: 0.0914, "vt": 0.0816, "hkb": 2.1767, "rpc": 0.3838, "excitator": 0.1467},
    "cv": {HUMAN: 0.3011, "vt": 0.1002, "hkb": 0.9400, "rpc": 0.7602, "excitator": 0.4859},
    "time_lag": {HUMAN: 0.2035, "vt": 0.1274, "hkb": 1.5192, "rpc": 0.0428, "excitator": -0.9674},
}
"""Zhai et al. (2017), Table 4, by score and follower: five people and four models tracking one
prerecorded reference signal; their optimal-control player (OPC) is our ``vt``, the Jirsa-Kelso
excitator (JKE) our ``excitator``, the human benchmark (HP) our `HUMAN`. Their CV is the norm of
the mean of exp(i relative phase), our ``cv``."""

PUBLISHED_ADAPTIVE_BOUNDS = {"position": 0.2, "velocity": 0.62}
"""Zhai et al. (2017): the adaptive player's position and velocity errors stay below these
(units, units/s), where the reactive-predictive one reaches 0.8 and 3."""

SCORES = (
    "rms",
    "rpe",
    "cv",
    "time_lag",
    "emd",
    "max_position_error",
    "max_velocity_error",
    "rms_velocity_error",
)
"""The scores of one trial, in table order."""


@dataclass
class BenchmarkResult:
    """What a benchmark run found.

    Attributes
    ----------
    trials
        One row per (follower, leader trial): the follower (a model name or `HUMAN`), the
        trial's label, the leader's group and `SCORES`.
    sessions
        The first trial's session of each follower, for the figures.
    """

    trials: pd.DataFrame
    sessions: dict[str, Session]

    def summary(self) -> pd.DataFrame:
        """Mean of each score per follower, with the trial count and Zhai et al.'s values.

        Without recorded human followers the `HUMAN` row has no trial and no score of ours,
        only Zhai et al.'s human benchmark.
        """
        grouped = self.trials.groupby("follower", sort=False)
        table = grouped[list(SCORES)].mean()
        table.insert(0, "trials", grouped.size())
        if HUMAN not in table.index:
            table.loc[HUMAN] = [0, *([math.nan] * len(SCORES))]
            table["trials"] = table["trials"].astype(int)
        for key, values in PUBLISHED.items():
            table[f"published_{key}"] = [values.get(name, math.nan) for name in table.index]
        return table

    def by_group(self) -> pd.DataFrame:
        """Mean of each score per leader group (a recording's group, as read) and follower."""
        return self.trials.groupby(["group", "follower"], sort=False)[list(SCORES)].mean()

    def ranking(self) -> list[str]:
        """Followers from the RPE nearest the human followers' to the farthest.

        The human RPE is the recorded followers' mean where there are any, else Zhai et al.'s.
        """
        table = self.summary()
        human = self.human_rpe()
        models = table.drop(index=HUMAN)
        return list((models["rpe"] - human).abs().sort_values().index)

    def human_rpe(self) -> float:
        """Return the recorded human followers' mean RPE, else Zhai et al.'s human benchmark."""
        recorded = self.trials.loc[self.trials["follower"] == HUMAN, "rpe"]
        return float(recorded.mean()) if len(recorded) else PUBLISHED["rpe"][HUMAN]


def relative_position_error(
    leader: Array, follower: Array, leader_velocity: Array, follower_velocity: Array
) -> float:
    """Zhai et al.'s relative position error of a follower: how far behind its leader it is.

    Zhai et al. (2017, section 6.2, after Słowiński et al. 2016), with x_1, x_2 the positions
    and v_1, v_2 the velocities of leader and follower::

        e(t) = (x_1 - x_2) sgn(v_1)   if sgn(v_1) = sgn(v_2) != 0
               |x_1 - x_2|            otherwise

    positive when the follower is behind its leader. **Choice**: the paper defines e(t) and
    reports one number per player; this is its mean over the samples.

    Parameters
    ----------
    leader, follower
        Positions (units), shape (n,).
    leader_velocity, follower_velocity
        Velocities (units/s), shape (n,).

    Returns
    -------
    float
        The mean of e(t) (units).
    """
    gap = leader - follower
    direction = np.sign(leader_velocity)
    same = (direction == np.sign(follower_velocity)) & (direction != 0.0)
    return float(np.mean(np.where(same, gap * direction, np.abs(gap))))


def score(session: Session, trim: float = TRIM) -> dict[str, float]:
    """`SCORES` of player 1 (the follower) against player 0 (the leader) after ``trim`` s."""
    metrics = session_metrics(session, trim=trim)
    kept = session.trimmed(trim) if trim > 0 else session
    x, v = kept.positions, kept.velocities
    return {
        "rms": metrics["rmse"],
        "rpe": relative_position_error(x[0], x[1], v[0], v[1]),
        "cv": metrics["phase_locking"],
        "time_lag": metrics["time_lag"],
        "emd": metrics["emd_players"],
        "max_position_error": float(np.max(np.abs(x[1] - x[0]))),
        "max_velocity_error": float(np.max(np.abs(v[1] - v[0]))),
        "rms_velocity_error": float(np.sqrt(np.mean((v[1] - v[0]) ** 2))),
    }


def model_follower(name: str) -> Player:
    """Build the follower a model name of `MODELS` (or a full partner spec) names."""
    spec = VIRTUAL_TRAINER_SPEC if name == "vt" else name
    return load_player(spec, "follower")


def check_models(names: Sequence[str]) -> list[str]:
    """Return the model names, refusing an unknown one or a bad parameter in one line."""
    unknown = [
        name for name in names if name not in MODELS and name.partition(":")[0] not in MODELS
    ]
    if unknown or not names:
        known = ",".join(MODELS)
        raise InputError(
            "--models", f"unknown model {unknown[0] if unknown else '(none)'}; give some of {known}"
        )
    for name in names:
        kind = MODEL_PARTNERS.get(name.partition(":")[0])
        if kind is None and name != "vt":
            raise InputError("--models", f"{name}: vt takes no parameters")
        if kind is not None:
            parse_options(name, kind.PARAMETERS)
    return list(names)


def run_benchmark(
    leaders: Sequence[Trial],
    models: Sequence[str],
    humans: Sequence[Trial] = (),
    progress: bool | None = None,
    follower: Callable[[str], Player] = model_follower,
) -> BenchmarkResult:
    """Let every model follow every leader, and score it and the human followers.

    Parameters
    ----------
    leaders
        The recorded leaders (any rate: replayed on the control grid).
    models
        Names of `MODELS` (a partner may carry parameters, ``adaptive:cp=30``).
    humans
        Recorded human followers, one per leader in the same order, or none.
    progress
        Show a progress bar (None: when standard error is a terminal).
    follower
        Builds a model's follower from its name.
    """
    if humans and len(humans) != len(leaders):
        raise InputError(
            "--human", f"give one human follower per leader: {len(humans)} for {len(leaders)}"
        )
    rows: list[dict[str, Any]] = []
    sessions: dict[str, Session] = {}
    pairs = [(name, i) for i in range(len(leaders)) for name in models]
    pairs += [(HUMAN, i) for i in range(len(humans))]
    disable = progress is False or (progress is None and not sys.stderr.isatty())
    for name, i in tqdm(pairs, disable=disable, unit="trial"):
        leader = RecordedPlayer(leaders[i], CONTROL_PERIOD)
        other = RecordedPlayer(humans[i], CONTROL_PERIOD) if name == HUMAN else follower(name)
        length = leader.track.shape[1]
        if name == HUMAN:
            length = min(length, other.track.shape[1])  # type: ignore[attr-defined]
        duration = (length - 1) * CONTROL_PERIOD
        if duration <= TRIM + 1.0:
            raise InputError(leaders[i].label or "leader", "too short to score (under 2 s)")
        session = play([leader, other], duration=duration, seed=0, roles=("leader", "follower"))
        trial = {"follower": name, "trial": leaders[i].label or f"trial {i}"}
        rows.append(trial | {"group": leaders[i].group or ""} | score(session))
        sessions.setdefault(name, session)
    return BenchmarkResult(pd.DataFrame(rows), sessions)
