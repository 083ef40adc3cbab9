"""A personal avatar checked against the person themselves (METHODS section 10, the proof).

Two checks, both against recordings the avatar never learned from:

- **Held-out solo trials.** Some of the person's solo trials are kept out of fitting
  (`split_held_out`). The velocity IMS of each held-out trial is compared (EMD) with that of each
  session the avatar played in validation, and that distance, as leader, with the person's own
  trial-to-trial EMD (every pair of their trials): an avatar that moves like the person is as
  far from a new trial of theirs as their trials are from one another.
- **Recordings with a partner.** Where the person played a dyad session (a file
  `mirror_avatar.session.load_session` reads), the avatar plays that session again against the
  partner's recorded track replayed open-loop (`mirror_avatar.players.RecordedPlayer`), in the
  person's place and role, and its CV, RMS and lag are set beside the person's.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from numpy.typing import NDArray

from mirror_avatar.engine.batch import play_compiled
from mirror_avatar.engine.loop import count_samples
from mirror_avatar.errors import InputError
from mirror_avatar.experiments.cyber_player import CRITERIA
from mirror_avatar.figures import plot_positions
from mirror_avatar.importing import excerpt
from mirror_avatar.likeness import Likeness, compare_motion, trial_velocity
from mirror_avatar.metrics import TRIM, session_metrics
from mirror_avatar.players import RecordedPlayer
from mirror_avatar.seeds import draw_seeds
from mirror_avatar.session import Session
from mirror_avatar.signature import compute_emd, compute_ims
from mirror_avatar.training.avatar import Avatar
from mirror_avatar.trials import DEFAULT_RATE, Trial, make_trial

Array = NDArray[np.float64]

HOLDOUT_EVERY = 4
"""By default one solo trial in this many is held out of fitting, at least one when the person
has `MIN_TRIALS_TO_HOLD_OUT` or more (**choice**)."""

MIN_TRIALS_TO_HOLD_OUT = 3
"""Fewest trials of which one is held out by default: two remain to fit, so the codebook size is
still chosen by leaving out whole trials (**choice**: short trials split in halves are too
few frames for it)."""

PARTNER_SEEDS = 5
"""Sessions the avatar plays against each replayed partner, seeded apart (**choice**: the
avatar's reference and exploration are random, so one session would be one draw)."""

TRACE_SECONDS = 30.0
"""Seconds of the person-against-avatar trace on the card."""

JUDGED_MOTION = "played as leader"
"""The avatar's motion the held-out verdict judges (**choice**: leading, the avatar moves in its
own way, as in a solo trial; a follower's motion is mostly its leader's, so its EMD measures the
partners and is shown, not judged)."""

OWN_RANGE = (5.0, 95.0)
"""Percentiles of the person's trial-to-trial EMD shown as their own range (**choice**)."""


def count_held_out(n_trials: int) -> int:
    """Return the default number of held-out trials: one in `HOLDOUT_EVERY`, at least one.

    None below `MIN_TRIALS_TO_HOLD_OUT` trials.
    """
    return max(1, n_trials // HOLDOUT_EVERY) if n_trials >= MIN_TRIALS_TO_HOLD_OUT else 0


def split_held_out(trials: Sequence[Trial], n_held_out: int) -> tuple[list[Trial], list[Trial]]:
    """Split the person's trials into those fitted and those held out.

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
class HeldOutProof:
    """EMDs of the held-out check (see the module docstring).

    Attributes
    ----------
    held_out
        Labels of the held-out trials.
    own
        EMD between the velocity IMS of every pair of the person's trials, shape (pairs,).
    to_avatar
        Source of the avatar's motion (``"played as follower"``...) -> EMD between each
        held-out trial's IMS and each of its sessions', shape (held-out x sessions,).
    likeness
        Source -> the human-likeness battery of its sessions against the held-out trials
        (`mirror_avatar.likeness.compare_motion`, the person's own variability from all their
        trials).
    """

    held_out: list[str]
    own: Array
    to_avatar: dict[str, Array]
    likeness: dict[str, Likeness] = field(default_factory=dict)

    @property
    def played(self) -> Array:
        """EMDs to the sessions the verdict judges (`JUDGED_MOTION`)."""
        return self.to_avatar[JUDGED_MOTION]

    @property
    def own_range(self) -> tuple[float, float]:
        """The person's own trial-to-trial EMD, `OWN_RANGE` percentiles."""
        lo, hi = np.percentile(self.own, OWN_RANGE)
        return float(lo), float(hi)

    @property
    def moves_like(self) -> bool:
        """Whether the median EMD to the held-out trials is within the person's own range."""
        return bool(np.median(self.played) <= self.own_range[1])

    def verdict(self) -> str:
        """One line: does the avatar move like the person."""
        lo, hi = self.own_range
        own = f"{hi:.4f}" if self.own.size == 1 else f"{lo:.4f}-{hi:.4f}"
        median = float(np.median(self.played))
        if self.moves_like:
            return (
                f"moves like the person: EMD to held-out trials {median:.4f} as leader, within "
                f"the person's own {own}"
            )
        return (
            f"moves unlike the person: EMD to held-out trials {median:.4f} as leader, above "
            f"the person's own {own}"
        )

    def table(self) -> pd.DataFrame:
        """Median and range of each EMD distribution, the person's own first."""
        rows = {"the person, trial to trial": self.own} | {
            f"avatar {source}": emd for source, emd in self.to_avatar.items()
        }
        return pd.DataFrame(
            {
                "EMD median": [float(np.median(v)) for v in rows.values()],
                f"EMD P{OWN_RANGE[0]:g}": [
                    float(np.percentile(v, OWN_RANGE[0])) for v in rows.values()
                ],
                f"EMD P{OWN_RANGE[1]:g}": [
                    float(np.percentile(v, OWN_RANGE[1])) for v in rows.values()
                ],
                "comparisons": [v.size for v in rows.values()],
            },
            index=list(rows),
        )

    def to_json_dict(self) -> dict[str, Any]:
        """Return the numbers for the avatar's summary."""
        lo, hi = self.own_range
        return {
            "held_out": self.held_out,
            "emd_to_held_out": float(np.median(self.played)),
            "own_emd_range": [lo, hi],
            "moves_like_the_person": self.moves_like,
            "verdict": self.verdict(),
            "likeness": {source: result.to_json_dict() for source, result in self.likeness.items()},
        }


def trial_ims(trial: Trial) -> Array:
    """Velocity IMS of a trial resampled to the toolkit's rate."""
    uniform = trial if trial.is_uniform and trial.rate == DEFAULT_RATE else trial.resampled()
    return compute_ims(uniform.velocity())


def prove_held_out(
    fitted: Sequence[Trial],
    held_out: Sequence[Trial],
    motion: Mapping[str, Sequence[Array]],
    rate: float = DEFAULT_RATE,
    seed: int = 0,
) -> HeldOutProof:
    """Compare held-out trials with the avatar's motion and with the person's own variation.

    Parameters
    ----------
    fitted, held_out
        The person's trials fitted and held out (at least one held out).
    motion
        Source -> the avatar's velocity (units/s) in each session.
    rate
        Sampling rate (Hz) of the sessions; the battery resamples the trials to it.
    seed
        Seeds the human-likeness battery of each source.
    """
    ims = [trial_ims(t) for t in (*fitted, *held_out)]
    own = np.array([compute_emd(a, b) for a, b in itertools.combinations(ims, 2)])
    held = ims[len(fitted) :]
    to_avatar = {
        source: np.array([compute_emd(h, compute_ims(v)) for h in held for v in velocities])
        for source, velocities in motion.items()
    }
    velocities = [trial_velocity(t, rate) for t in (*fitted, *held_out)]
    likeness = {
        source: compare_motion(velocities[len(fitted) :], sessions, velocities, rate, seed=seed)
        for source, sessions in motion.items()
    }
    return HeldOutProof([t.label for t in held_out], own, to_avatar, likeness)


@dataclass
class PartnerSession:
    """A dyad session the person played, with whom the avatar replaces."""

    name: str
    session: Session
    person: int

    @property
    def partner(self) -> int:
        """The partner's player index."""
        return 1 - self.person


def find_person(name: str, session: Session, person_label: str) -> PartnerSession:
    """Find the person in a dyad session by label (``LABEL`` or ``person LABEL``).

    Raises
    ------
    InputError
        The session is not a dyad, or no player carries the label.
    """
    if session.n_players != 2:
        raise InputError(name, f"{session.n_players} players: --with-partner takes dyad sessions")
    wanted = (person_label, f"person {person_label}")
    matches = [k for k, label in enumerate(session.labels) if label in wanted]
    if len(matches) != 1:
        raise InputError(
            name,
            f"no single player labelled {excerpt(person_label)} (labels "
            f"{', '.join(excerpt(label) for label in session.labels)}): give --person-label",
        )
    return PartnerSession(name, session, matches[0])


def dyad_numbers(session: Session, partner: int) -> dict[str, float]:
    """CV, RMS (units) and the partner's lead (s) of a dyad session after the transient."""
    metrics = session_metrics(session, trim=TRIM)
    lag = metrics["time_lag"] if partner == 0 else -metrics["time_lag"]
    return {"cv": metrics["phase_locking"], "rms": metrics["rmse"], "lag": lag}


def replay_partner(
    avatar: Avatar, recorded: PartnerSession, n_seeds: int, seed: int
) -> list[Session]:
    """Play the avatar in the person's place and role against the partner's recorded track."""
    session = recorded.session
    role = session.roles[recorded.person]
    player = avatar.player(role)
    track = make_trial(
        session.times - session.times[0],
        session.positions[recorded.partner],
        label=f"{session.labels[recorded.partner]} (replayed)",
    )
    partner = RecordedPlayer(track, player.period)
    lineup = [partner, player] if recorded.partner == 0 else [player, partner]
    n_samples = count_samples(session.duration, player.period)
    return [
        play_compiled(lineup, n_samples, s, roles=session.roles)
        for s in draw_seeds([seed, 2], n_seeds)
    ]


@dataclass
class PartnerProof:
    """The avatar against replayed partners (see the module docstring).

    Attributes
    ----------
    records
        One row per session and player (``person`` or ``avatar``): ``session``, ``player``,
        ``cv``, ``rms`` (units), ``lag`` (s, positive when the partner is ahead).
    example
        The first session as recorded and the avatar's first replay of it.
    """

    records: pd.DataFrame
    example: tuple[PartnerSession, Session]

    def means(self) -> pd.DataFrame:
        """Mean CV, RMS and lag per session and player."""
        return self.records.groupby(["session", "player"], sort=False)[["cv", "rms", "lag"]].mean()

    def table(self) -> pd.DataFrame:
        """`means` with the card's column names."""
        names = {"cv": "CV", "rms": "RMS (units)", "lag": "partner ahead by (s)"}
        return self.means().rename(columns=names)

    def close_sessions(self) -> int:
        """Sessions where the avatar's mean CV and RMS are within the criteria's difference."""
        means = self.means()
        close = 0
        for name in self.records["session"].unique():
            person, avatar = means.loc[(name, "person")], means.loc[(name, "avatar")]
            close += bool(
                abs(avatar["cv"] - person["cv"]) <= CRITERIA["max_difference"]
                and abs(avatar["rms"] - person["rms"]) <= CRITERIA["max_difference"]
            )
        return close

    def verdict(self) -> str:
        """One line: the avatar's CV, RMS and lag against the person's, over all sessions."""
        mean = self.records.groupby("player")[["cv", "rms", "lag"]].mean()
        avatar, person = mean.loc["avatar"], mean.loc["person"]
        n = self.records["session"].nunique()
        return (
            f"with a replayed partner CV {avatar['cv']:.2f} (person {person['cv']:.2f}), RMS "
            f"{avatar['rms']:.3f} ({person['rms']:.3f}), partner ahead by {avatar['lag']:.2f} s "
            f"({person['lag']:.2f} s); CV and RMS within {CRITERIA['max_difference']:g} of the "
            f"person's in {self.close_sessions()} of {n} sessions"
        )

    def to_json_dict(self) -> dict[str, Any]:
        """Return the numbers for the avatar's summary."""
        means = self.means().reset_index()
        return {
            "sessions": means.to_dict(orient="records"),
            "close_sessions": self.close_sessions(),
            "verdict": self.verdict(),
        }


def prove_with_partners(
    avatar: Avatar, recorded: Sequence[PartnerSession], n_seeds: int = PARTNER_SEEDS, seed: int = 0
) -> PartnerProof:
    """Replay each recorded partner against the avatar and compare with the person."""
    rows: list[dict[str, Any]] = []
    example: tuple[PartnerSession, Session] | None = None
    for dyad in recorded:
        rows.append(
            {"session": dyad.name, "player": "person"} | dyad_numbers(dyad.session, dyad.partner)
        )
        replays = replay_partner(avatar, dyad, n_seeds, seed)
        example = example or (dyad, replays[0])
        rows += [
            {"session": dyad.name, "player": "avatar"} | dyad_numbers(replay, dyad.partner)
            for replay in replays
        ]
    if example is None:
        raise InputError("--with-partner", "no sessions given")
    return PartnerProof(pd.DataFrame(rows), example)


@dataclass
class Proof:
    """The avatar checked against the person: held-out trials and replayed partners (or None)."""

    held_out: HeldOutProof | None
    partners: PartnerProof | None
    held_out_trials: Sequence[Trial]

    def verdict(self) -> str:
        """One line for the card and the live page."""
        parts = [p.verdict() for p in (self.held_out, self.partners) if p is not None]
        if not parts:
            return (
                "is not checked against the person: no trial was held out of fitting (record "
                f"{MIN_TRIALS_TO_HOLD_OUT} or more solo trials)"
            )
        return "; ".join(parts)

    def to_json_dict(self) -> dict[str, Any]:
        """Return the proof's numbers and its verdict, for the avatar's summary."""
        return {
            "verdict": self.verdict(),
            "held_out": None if self.held_out is None else self.held_out.to_json_dict(),
            "partners": None if self.partners is None else self.partners.to_json_dict(),
        }

    def tables(self) -> dict[str, pd.DataFrame]:
        """Return the card's tables of the proof, by caption."""
        tables = {}
        if self.held_out is not None:
            tables[
                f"Velocity IMS EMD to the held-out trials ({', '.join(self.held_out.held_out)})"
            ] = self.held_out.table()
            for source, result in self.held_out.likeness.items():
                tables[f"Human-likeness of the avatar {source}, against the held-out trials"] = (
                    result.table()
                )
        if self.partners is not None:
            tables["The person and the avatar against their partner's recorded track (mean)"] = (
                self.partners.table()
            )
        return tables

    def plot_trace(self, played: Session, name: str) -> Figure | None:
        """Plot the person against the avatar, positions over the first `TRACE_SECONDS`.

        With a partner session: the partner as recorded, the person, and the avatar's first
        replay in the person's place. Otherwise the first held-out trial beside ``played`` (a
        session the avatar played, its player 1). None when there is neither.
        """
        if self.partners is not None:
            dyad, replay = self.partners.example
            recorded = dyad.session
            keep = recorded.times - recorded.times[0] <= TRACE_SECONDS
            times = recorded.times[keep] - recorded.times[0]
            on_grid = np.interp(
                times, replay.times - replay.times[0], replay.positions[dyad.person]
            )
            return plot_positions(
                times,
                {
                    f"partner ({recorded.labels[dyad.partner]}, recorded)": (
                        recorded.positions[dyad.partner][keep]
                    ),
                    name: recorded.positions[dyad.person][keep],
                    f"avatar of {name}": on_grid,
                },
                f"{name} and the avatar with the same partner ({Path(dyad.name).name})",
            )
        if not self.held_out_trials:
            return None
        trial = self.held_out_trials[0]
        times = played.times - played.times[0]
        times = times[times <= min(TRACE_SECONDS, trial.duration)]
        person = np.interp(times, trial.times - trial.times[0], trial.positions)
        return plot_positions(
            times,
            {
                f"{name} ({trial.label}, held out)": person,
                f"avatar of {name} (as {played.roles[1]})": played.positions[1][: times.size],
            },
            f"{name}'s held-out trial and the avatar playing",
        )
