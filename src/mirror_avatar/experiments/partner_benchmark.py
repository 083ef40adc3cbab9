"""Followers side by side following recorded leaders, as Zhai et al. (2017) compare partners.

Each follower a SPEC names (`mirror_avatar.specs`: a partner from the literature, a personal
avatar, a trained policy, a virtual trainer; ``vt`` the bundled slow one) follows each recorded
leader (a `RecordedPlayer`) in the Python step loop; each recorded human follower, when given, is
scored against its own leader the same way. Scores per trial (`SCORES`): RMS position error,
relative position error (`relative_position_error`), phase locking R of the relative phase, time
lag, the normalised EMD between the follower's and the leader's velocity distributions
(`mirror_avatar.metrics.session_metrics`), the follower's amplitude relative to its leader's, and
the largest and RMS velocity errors. The first `TRIM` seconds are dropped: the partners start at
rest. Zhai et al.'s published values are in `mirror_avatar.experiments.published_partners`, never
in these tables.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from tqdm import tqdm

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.engine.loop import play
from mirror_avatar.files.trials import Trial
from mirror_avatar.metrics import session_metrics
from mirror_avatar.players import Player, RecordedPlayer
from mirror_avatar.sessions.session import Session
from mirror_avatar.specs import MODEL_PARTNERS, load_player

Array = NDArray[np.float64]

TRIM = 1.0
"""Seconds dropped at the start of every trial before scoring (**choice**)."""

VIRTUAL_TRAINER = "vt"
"""The name the benchmark gives the optimal-control virtual trainer of `VIRTUAL_TRAINER_SPEC`."""

VIRTUAL_TRAINER_SPEC = "bundled:slow"
"""The optimal-control virtual trainer the benchmark calls ``vt`` (**choice**: a signature learnt
from the bundled slow trials, the follower preset)."""

MODELS = (*MODEL_PARTNERS, VIRTUAL_TRAINER)
"""The followers the benchmark runs when none are named: the partners from the literature and
``vt``."""

HUMAN = "human"
"""The row of the recorded human followers."""

PUBLISHED_ADAPTIVE_BOUNDS = {"position": 0.2, "velocity": 0.62}
"""Zhai et al. (2017): the adaptive player's position and velocity errors stay below these
(units, units/s), where the reactive-predictive one reaches 0.8 and 3."""

SCORES = (
    "rms",
    "rpe",
    "phase_locking",
    "time_lag",
    "emd",
    "amplitude_ratio",
    "max_position_error",
    "max_velocity_error",
    "rms_velocity_error",
)
"""The scores of one trial, in table order (see `score`)."""


@dataclass
class BenchmarkResult:
    """What a benchmark run found.

    Attributes
    ----------
    trials
        One row per (follower, leader trial): the follower (its SPEC, or `HUMAN`), the
        trial's label, the leader's group and `SCORES`.
    sessions
        The first trial's session of each follower, for the figures.
    """

    trials: pd.DataFrame
    sessions: dict[str, Session]

    def summary(self) -> pd.DataFrame:
        """Mean of each score per follower, with the trial count (`HUMAN` only if recorded)."""
        grouped = self.trials.groupby("follower", sort=False)
        table = grouped[list(SCORES)].mean()
        table.insert(0, "trials", grouped.size())
        return table

    def by_group(self) -> pd.DataFrame:
        """Mean of each score per leader group (a recording's group, as read) and follower."""
        return self.trials.groupby(["group", "follower"], sort=False)[list(SCORES)].mean()

    def followers(self) -> list[str]:
        """Return the followers run (not `HUMAN`), in the order given."""
        return [name for name in self.trials["follower"].unique() if name != HUMAN]


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
    """`SCORES` of player 1 (the follower) against player 0 (the leader) after ``trim`` s.

    ``phase_locking`` is R = |mean exp(i dphi)| of the relative phase (1 = locked;
    `mirror_avatar.metrics.session_metrics`); ``amplitude_ratio`` the standard deviation of the
    follower's positions over the leader's (1 = the leader's amplitude, NaN for a still leader).
    """
    metrics = session_metrics(session, trim=trim)
    kept = session.trimmed(trim) if trim > 0 else session
    x, v = kept.positions, kept.velocities
    spread = float(np.std(x[0]))
    return {
        "rms": metrics["rmse"],
        "rpe": relative_position_error(x[0], x[1], v[0], v[1]),
        "phase_locking": metrics["phase_locking"],
        "time_lag": metrics["time_lag"],
        "emd": metrics["emd_players"],
        "amplitude_ratio": float(np.std(x[1])) / spread if spread > 0 else float("nan"),
        "max_position_error": float(np.max(np.abs(x[1] - x[0]))),
        "max_velocity_error": float(np.max(np.abs(v[1] - v[0]))),
        "rms_velocity_error": float(np.sqrt(np.mean((v[1] - v[0]) ** 2))),
    }


def make_follower(spec: str) -> Player:
    """Build the follower a SPEC names (``vt``: `VIRTUAL_TRAINER_SPEC`) in the follower role."""
    return load_player(VIRTUAL_TRAINER_SPEC if spec == VIRTUAL_TRAINER else spec, "follower")


def check_followers(specs: Sequence[str], option: str = "--models") -> list[str]:
    """Return the SPECs, each built once, refusing a bad one in one line naming ``option``.

    Raises
    ------
    InputError
        ``OPTION: SPEC: problem`` for a SPEC `mirror_avatar.specs.load_player` refuses (an
        unknown name, a missing or unreadable file, a policy not trained to follow, a bad
        parameter); ``OPTION: ...`` for none, a SPEC given twice or one named `HUMAN`.
    """
    if not specs:
        raise InputError(option, f"no follower named; give SPECs such as {','.join(MODELS)}")
    repeated = sorted({spec for spec in specs if list(specs).count(spec) > 1})
    if repeated:
        raise InputError(option, f"{repeated[0]} is given twice")
    if HUMAN in specs:
        raise InputError(option, f"{HUMAN!r} names the recorded human followers (--humans)")
    for spec in specs:
        try:
            make_follower(spec)
        except InputError as error:
            raise InputError(option, str(error)) from None
    return list(specs)


def run_benchmark(
    leaders: Sequence[Trial],
    followers: Sequence[str],
    humans: Sequence[Trial] = (),
    progress: bool | None = None,
    follower: Callable[[str], Player] = make_follower,
) -> BenchmarkResult:
    """Let every follower follow every leader, and score it and the human followers.

    Parameters
    ----------
    leaders
        The recorded leaders (any rate: replayed on the control grid).
    followers
        SPECs of the followers (`check_followers`).
    humans
        Recorded human followers, ``humans[i]`` following ``leaders[i]``, or none.
    progress
        Show a progress bar (None: when standard error is a terminal).
    follower
        Builds a follower from its SPEC.
    """
    if humans and len(humans) != len(leaders):
        raise InputError(
            "--humans", f"give one human follower per leader: {len(humans)} for {len(leaders)}"
        )
    rows: list[dict[str, Any]] = []
    sessions: dict[str, Session] = {}
    pairs = [(name, i) for i in range(len(leaders)) for name in followers]
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
