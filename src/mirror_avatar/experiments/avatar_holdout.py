"""A personal avatar checked against the person's held-out solo trials, role by role (METHODS 10).

Every trial is held out in turn (`make_folds`): with at most `MAX_FOLDS` trials, leave-one-out;
with more, `MAX_FOLDS` folds of trials spread over the recording order. For each fold an avatar
is built as the avatar itself is, on the other trials (`build_fold`), and plays every role: as
follower and as leader with each partner (the validation's sessions,
`mirror_avatar.experiments.cyber_player.validate`), and as a group member with some of the
partners on a complete graph (`play_group`). The person's virtual trainer plays the same sessions.
The velocity IMS of each held-out trial is compared (EMD) with that of each session, and the
median over them with the person's own trial-to-trial EMD (every pair of their trials): a role is
**flagged** when that median is above the 95th percentile of the person's own
(`HeldOutProof.flagged`), the avatar being further from the person than their own variability
allows.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import draw_seeds
from mirror_avatar.dynamics import preset
from mirror_avatar.engine.batch import play_compiled
from mirror_avatar.engine.loop import count_samples
from mirror_avatar.experiments.cyber_player import SESSION_SECONDS, train_target, validate
from mirror_avatar.experiments.group import choose_members
from mirror_avatar.files.trials import DEFAULT_RATE, Trial
from mirror_avatar.learning.acceleration_player import AccelerationPlayer
from mirror_avatar.metrics import TRIM
from mirror_avatar.motion.strokes import StrokeGenerator
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.likeness import (
    MAX_UNITS,
    Likeness,
    compare_motion,
    spread,
    trial_velocity,
)
from mirror_avatar.signatures.signature import compute_emd, compute_ims
from mirror_avatar.training.cast import Cast, VirtualTrainerSpec
from mirror_avatar.training.imitation import Agent

Array = NDArray[np.float64]

CHECKED_ROLES = ("follower", "leader", "group member")
"""The roles the avatar plays, each checked against the person."""

MIN_TRIALS_TO_HOLD_OUT = 3
"""Fewest trials the avatar is checked against: two remain to fit each fold, so the codebook
size is still chosen by leaving out whole trials (**choice**: short trials split in halves are
too few frames for it)."""

TRAINER_MARGIN = 1.1
"""A flagged follower or group member within this factor of the person's virtual trainer's
median EMD is as far as the trainer (**choice**, the fidelity goal of METHODS section 4)."""

MAX_FOLDS = 5
"""Most avatars built for the check (**choice**: leave-one-out up to this many trials, then as
many folds, so that the check costs at most this many extra trainings)."""

OWN_RANGE = (5.0, 95.0)
"""Percentiles of the person's trial-to-trial EMD shown as their own range; a role whose median
EMD to the held-out trials is above the upper one is flagged (**choice**)."""


def make_folds(n_trials: int) -> list[list[int]]:
    """Return the held-out trials of each fold, indices into the recording order.

    Trial ``j`` is held out in fold ``j % k``, ``k = min(n_trials, MAX_FOLDS)`` (leave-one-out
    up to `MAX_FOLDS` trials); no fold below `MIN_TRIALS_TO_HOLD_OUT` trials.
    """
    if n_trials < MIN_TRIALS_TO_HOLD_OUT:
        return []
    k = min(n_trials, MAX_FOLDS)
    return [list(range(i, n_trials, k)) for i in range(k)]


def split_held_out(trials: Sequence[Trial], n_held_out: int) -> tuple[list[Trial], list[Trial]]:
    """Split the person's trials once into those fitted and ``n_held_out`` held out.

    The held-out trials are spread over the recording order: trial ``(i + 1) * n // (k + 1)``
    for ``i < k`` (one of two: the second; one of four: the third).

    Raises
    ------
    InputError
        ``n_held_out`` negative or leaving no trial to fit.
    """
    n = len(trials)
    if not 0 <= n_held_out < n:
        raise InputError(
            "--holdout", f"{n_held_out} held-out trials of {n}: keep at least one to fit"
        )
    held = {(i + 1) * n // (n_held_out + 1) for i in range(n_held_out)}
    return (
        [t for k, t in enumerate(trials) if k not in held],
        [t for k, t in enumerate(trials) if k in held],
    )


@dataclass
class RoleMotion:
    """Velocities (units/s) of the sessions of one role, after the transient.

    Attributes
    ----------
    avatar
        The avatar's velocity in each session.
    trainer
        The person's virtual trainer's in the same sessions (same partners and seeds).
    """

    avatar: list[Array]
    trainer: list[Array]


def play_group(cast: Cast, player: AccelerationPlayer, n_sessions: int, seed: int) -> RoleMotion:
    """Play the avatar (its follower policy) and the person's virtual trainer in a group.

    The group is `mirror_avatar.experiments.group.choose_members`'s: the first and last training
    partners, the unseen one and the person, every one seeing every other (complete graph), all
    with the group preset; the person's virtual trainer or ``player`` is the last, the same seeds
    for both.
    """
    members = [cast.trainers[i] for i in choose_members(cast)]
    *partners, person = [m.player(preset("group")) for m in members]
    roles = ["group"] * len(members)
    n_samples = count_samples(SESSION_SECONDS, player.period)
    motion = RoleMotion([], [])
    for s in draw_seeds([seed, 3], n_sessions):
        for last, into in ((person, motion.trainer), (player, motion.avatar)):
            session = play_compiled([*partners, last], n_samples, s, roles=roles)
            into.append(session.trimmed(TRIM).velocities[-1])
    return motion


def dyad_motion(velocities: Mapping[str, list[Array]], person: str) -> RoleMotion:
    """Return one role's motion from `validate`'s velocities (``person``: the target's label)."""
    return RoleMotion(velocities["cyber player"], velocities[person])


@dataclass
class Fold:
    """One fold of the check.

    The trials held out, the motion by role of the avatar built without them, and its first
    session as leader.
    """

    held_out: list[Trial]
    motion: dict[str, RoleMotion]
    example: Session | None = None


def build_fold(
    cast: Cast,
    fitted: Sequence[Trial],
    held_out: Sequence[Trial],
    sessions: tuple[int, int],
    seed: int,
    n_jobs: int,
    agent: Agent,
    scheduler: str | None,
) -> Fold:
    """Build an avatar on ``fitted`` as `create_avatar` does and play it in every role.

    ``cast`` is the avatar's own (its partners); the person in it is replaced by a virtual
    trainer of a stroke generator (the default motion model) fitted on ``fitted`` alone, the same
    seed. ``sessions``: training
    sessions per role, and sessions per partner (and groups) played for the check.
    """
    n_train, n_check = sessions
    generator = StrokeGenerator(rate=DEFAULT_RATE, random_state=seed).fit(fitted)
    label = cast.trainers[cast.target].label
    trainers = list(cast.trainers)
    trainers[cast.target] = VirtualTrainerSpec(label, (), generator)
    fold_cast = Cast(trainers, cast.target, cast.seen, cast.unseen, cast.whole_people)
    motion, players, examples = {}, {}, {}
    for role in ("follower", "leader"):
        players[role], _ = train_target(fold_cast, role, n_train, seed, n_jobs, agent, scheduler)
        _, velocities, (_, examples[role]) = validate(players[role], fold_cast, role, n_check, seed)
        motion[role] = dyad_motion(velocities, label)
    motion["group member"] = play_group(fold_cast, players["follower"], n_check, seed)
    return Fold(list(held_out), motion, examples["leader"])


@dataclass
class HeldOutProof:
    """EMDs of the held-out check, by role (see the module docstring).

    Attributes
    ----------
    folds
        Labels of the trials held out of each fold's avatar.
    n_trials
        The person's trials.
    own
        EMD between the velocity IMS of every pair of the person's trials, shape (pairs,).
    to_avatar, to_trainer
        Role -> EMD between each held-out trial's IMS and that of each session its fold's
        avatar (or the person's virtual trainer) played, shape (comparisons,).
    likeness
        Role -> the human-likeness battery of the avatar's sessions against the held-out trials
        (`mirror_avatar.signatures.likeness.compare_motion`, the person's own variability from all
        their trials; with several folds, the sessions of every fold against every held-out trial,
        at most `mirror_avatar.signatures.likeness.MAX_UNITS` sessions spread over the folds).
    """

    folds: list[list[str]]
    n_trials: int
    own: Array
    to_avatar: dict[str, Array]
    to_trainer: dict[str, Array]
    likeness: dict[str, Likeness] = field(default_factory=dict)

    @property
    def held_out(self) -> list[str]:
        """Every held-out trial's label."""
        return [label for fold in self.folds for label in fold]

    @property
    def own_range(self) -> tuple[float, float]:
        """The person's own trial-to-trial EMD, `OWN_RANGE` percentiles."""
        lo, hi = np.percentile(self.own, OWN_RANGE)
        return float(lo), float(hi)

    def median(self, role: str) -> float:
        """Median EMD from the avatar in ``role`` to the held-out trials."""
        return float(np.median(self.to_avatar[role]))

    def ratio(self, role: str) -> float:
        """`median` over the median of the person's own trial-to-trial EMD."""
        return self.median(role) / float(np.median(self.own))

    def flagged(self, role: str) -> bool:
        """Whether the avatar in ``role`` is further from the person than their variability allows.

        The rule: its median EMD to the held-out trials above the upper `OWN_RANGE` percentile
        of the person's own trial-to-trial EMD.
        """
        return self.median(role) > self.own_range[1]

    def scheme(self) -> str:
        """How the trials were held out, in a few words."""
        n, k = self.n_trials, len(self.folds)
        if k == 1:
            return f"{len(self.folds[0])} of {n} trials held out of fitting"
        if all(len(fold) == 1 for fold in self.folds):
            return f"leave-one-out over {n} trials"
        return f"{k} folds over {n} trials"

    def explain_scheme(self) -> str:
        """How the trials were held out, in a sentence."""
        k = len(self.folds)
        if k == 1:
            return f"{self.scheme().capitalize()}: the avatar was fitted on the others."
        left = "one" if len(self.held_out) == k else "a fold"
        return (
            f"Checked by {self.scheme()}: the avatar is fitted on every trial, and {k} more "
            f"avatars, each built the same way without {left}, are compared with the trials "
            "they never saw."
        )

    def trainer_median(self, role: str) -> float:
        """Median EMD from the person's virtual trainer in ``role`` to the held-out trials."""
        return float(np.median(self.to_trainer[role]))

    def as_far_as_trainer(self, role: str) -> bool:
        """Whether the avatar in ``role`` is within `TRAINER_MARGIN` of the trainer's median EMD."""
        return self.median(role) <= TRAINER_MARGIN * self.trainer_median(role)

    def role_verdict(self, role: str) -> str:
        """Say in a sentence whether the avatar in ``role`` moves like the person, and how far.

        The sentence names its reference: the person's held-out solo trials, a human reference
        for the leader (who moves as in solo play); for a follower or a group member, no human
        reference exists (the person was not recorded in that role), and the person's virtual
        trainer in the same sessions is set beside it. A flagged role ends with the next step
        (`next_step`).
        """
        hi = self.own_range[1]
        median, trainer = self.median(role), self.trainer_median(role)
        numbers = (
            f"its median EMD to the person's held-out solo trials is {median:.4f}, "
            f"{self.ratio(role):.1f} x their own trial-to-trial median {np.median(self.own):.4f}"
        )
        context = f" The person's virtual trainer in the same sessions: {trainer:.4f}."
        if role != "leader":
            context = (
                f" No human reference exists for the {role}: the person was not recorded in this "
                f"role, so the person's virtual trainer in the same sessions, {trainer:.4f}, is "
                "the reference beside it."
            )
        if self.flagged(role):
            return (
                f"As {role}, FLAGGED: the avatar is further from the person than their own "
                f"variability allows: {numbers}, above their 95th percentile {hi:.4f}."
                + context
                + f" {self.next_step(role)}"
            )
        return (
            f"As {role}, the avatar moves like the person: {numbers}, within their own range "
            f"(95th percentile {hi:.4f})." + context
        )

    def short_step(self, role: str) -> str:
        """Say `next_step` in a few words, for the one-line verdict."""
        if role == "leader":
            return "next: record more or longer solo trials"
        if self.as_far_as_trainer(role):
            return f"the person's virtual trainer is as far as {role} (no human reference)"
        return "next: train longer (--sessions)"

    def next_step(self, role: str) -> str:
        """Say what a person can do about a flagged role, in a sentence."""
        if role == "leader":
            return (
                "Next: record more or longer solo trials (five of a minute or more) and create "
                "the avatar again."
            )
        if self.as_far_as_trainer(role):
            return (
                "The person's virtual trainer is as far, so the distance is the role's, not the "
                f"avatar's: trust the avatar as {role} as far as the virtual trainer, and record "
                "the person in this role (--with-partner) for a human reference."
            )
        return (
            "It is further than the person's virtual trainer too: train longer (--sessions "
            "above the default) or trust the avatar in the roles not flagged."
        )

    def verdict(self) -> str:
        """One line over every role: where the avatar moves like the person, where it is flagged."""
        like = [role for role in self.to_avatar if not self.flagged(role)]
        flagged = [role for role in self.to_avatar if role not in like]
        hi, scheme = self.own_range[1], self.scheme()
        if not flagged:
            return (
                f"moves like the person as {_join(like)}: median EMD to held-out trials within "
                f"the person's own 95th percentile {hi:.4f} ({scheme})"
            )
        times = [f"{flagged[0]} ({self.ratio(flagged[0]):.1f} x the person's own EMD)"]
        times += [f"{role} ({self.ratio(role):.1f} x)" for role in flagged[1:]]
        rule = f"median EMD to held-out trials above the person's own 95th percentile {hi:.4f}"
        step = "; " + self.short_step(flagged[0])
        if not like:
            return f"moves unlike the person, FLAGGED as {_join(times)}: {rule} ({scheme}){step}"
        return (
            f"moves like the person as {_join(like)}, but is FLAGGED as {_join(times)}: {rule} "
            f"({scheme}){step}"
        )

    def table(self) -> pd.DataFrame:
        """Tabulate the person's own EMD and the avatar's in each role: median, range, flag."""
        rows: dict[str, dict[str, Any]] = {
            "the person, trial to trial": _describe(self.own) | {"verdict": "their own range"}
        }
        for role, emd in self.to_avatar.items():
            rows[f"the avatar as {role}"] = _describe(emd) | {
                "median / the person's own median": self.ratio(role),
                "the person's virtual trainer in the same sessions, median": float(
                    np.median(self.to_trainer[role])
                ),
                "verdict": (
                    "FLAGGED: above the person's own 95th percentile"
                    if self.flagged(role)
                    else "within the person's own range"
                ),
            }
        columns = ["median EMD", "median / the person's own median", "5th percentile",
                   "95th percentile", "the person's virtual trainer in the same sessions, median",
                   "comparisons", "verdict"]  # fmt: skip
        return pd.DataFrame.from_dict(rows, orient="index")[columns]

    def to_json_dict(self) -> dict[str, Any]:
        """Return the numbers for the avatar's summary."""
        lo, hi = self.own_range
        return {
            "folds": self.folds,
            "scheme": self.scheme(),
            "own_emd_range": [lo, hi],
            "own_emd_median": float(np.median(self.own)),
            "roles": {
                role: {
                    "emd_to_held_out": self.median(role),
                    "ratio_to_own": self.ratio(role),
                    "trainer_emd_to_held_out": float(np.median(self.to_trainer[role])),
                    "flagged": self.flagged(role),
                    "verdict": self.role_verdict(role),
                }
                for role in self.to_avatar
            },
            "verdict": self.verdict(),
            "likeness": {role: result.to_json_dict() for role, result in self.likeness.items()},
        }


def _describe(emd: Array) -> dict[str, Any]:
    lo, hi = np.percentile(emd, OWN_RANGE)
    return {
        "median EMD": float(np.median(emd)),
        "5th percentile": float(lo),
        "95th percentile": float(hi),
        "comparisons": emd.size,
    }


def _join(items: Sequence[str]) -> str:
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} and {items[-1]}"


def trial_ims(trial: Trial) -> Array:
    """Velocity IMS of a trial resampled to the toolkit's rate."""
    uniform = trial if trial.is_uniform and trial.rate == DEFAULT_RATE else trial.resampled()
    return compute_ims(uniform.velocity())


def prove_held_out(
    trials: Sequence[Trial], folds: Sequence[Fold], rate: float = DEFAULT_RATE, seed: int = 0
) -> HeldOutProof:
    """Compare each fold's held-out trials with its avatar's motion and the person's own variation.

    Parameters
    ----------
    trials
        All the person's trials (their own variability).
    folds
        The held-out trials of each fold and the motion of the avatar built without them.
    rate
        Sampling rate (Hz) of the sessions; the battery resamples the trials to it.
    seed
        Seeds the human-likeness battery of each role.
    """
    own = np.array(
        [compute_emd(a, b) for a, b in itertools.combinations([trial_ims(t) for t in trials], 2)]
    )
    roles = list(folds[0].motion)
    to_avatar, to_trainer = {}, {}
    for role in roles:
        to_avatar[role] = _emds(folds, role, "avatar")
        to_trainer[role] = _emds(folds, role, "trainer")
    held = [trial_velocity(t, rate) for fold in folds for t in fold.held_out]
    everyone = [trial_velocity(t, rate) for t in trials]
    likeness = {
        role: compare_motion(
            held,
            spread([v for fold in folds for v in fold.motion[role].avatar], MAX_UNITS),
            everyone,
            rate,
            seed=seed,
        )
        for role in roles
    }
    return HeldOutProof(
        [[t.label for t in fold.held_out] for fold in folds],
        len(trials),
        own,
        to_avatar,
        to_trainer,
        likeness,
    )


def _emds(folds: Sequence[Fold], role: str, who: str) -> Array:
    """EMD between each held-out trial and each of its fold's sessions of ``who`` in ``role``."""
    emds = []
    for fold in folds:
        played = [compute_ims(v) for v in getattr(fold.motion[role], who)]
        for trial in fold.held_out:
            held = trial_ims(trial)
            emds += [compute_emd(held, ims) for ims in played]
    return np.array(emds)
