"""A personal avatar checked against the person themselves (METHODS section 10, the proof).

Two checks, both against recordings the avatar never learned from:

- **Held-out solo trials**, in every role the avatar plays (`mirror_avatar.experiments.
  avatar_holdout`): each trial held out in turn, an avatar built without it, the EMD of its
  velocity IMS to the avatar's sessions against the person's own trial-to-trial EMD, a role
  flagged where the avatar is further from the person than their own variability allows.
- **Recordings with a partner.** Where the person played a dyad session (a file
  `mirror_avatar.sessions.loading.load_session` reads), the avatar plays that session again against
  the partner's recorded track replayed open-loop (`mirror_avatar.players.RecordedPlayer`), in the
  person's place and role, and its CV, RMS and lag are set beside the person's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import draw_seeds
from mirror_avatar.engine.batch import play_compiled
from mirror_avatar.engine.loop import count_samples
from mirror_avatar.experiments.avatar_holdout import MIN_TRIALS_TO_HOLD_OUT, HeldOutProof
from mirror_avatar.experiments.cyber_player import CRITERIA
from mirror_avatar.figures.sessions import plot_positions
from mirror_avatar.files.importing import excerpt
from mirror_avatar.files.trials import Trial, make_trial
from mirror_avatar.metrics import TRIM, session_metrics
from mirror_avatar.players import RecordedPlayer
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.likeness import MAX_UNITS
from mirror_avatar.training.avatar import Avatar

PARTNER_SEEDS = 5
"""Sessions the avatar plays against each replayed partner, seeded apart (**choice**: the
avatar's reference and exploration are random, so one session would be one draw)."""

TRACE_SECONDS = 30.0
"""Seconds of the person-against-avatar trace on the card."""

LIKENESS_HEADERS = {
    "to held-out": "avatar to the held-out trials",
    "person's own": "the person's own, trial to trial",
    "ratio": "ratio to the person's own",
    "spread": "between the avatar's sessions",
    "p": "p-value (permutations by trial)",
}
"""The card's headers of `mirror_avatar.signatures.likeness.Likeness.table`'s columns."""


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
    """The avatar checked against the person: held-out trials and replayed partners (or None).

    ``example`` is a held-out trial and a session the avatar built without it played as leader
    (its player 1), for the trace on the card.
    """

    held_out: HeldOutProof | None
    partners: PartnerProof | None
    example: tuple[Trial, Session] | None = None

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
            held = self.held_out
            tables[
                "Velocity IMS EMD from the avatar in each role to the person's held-out trials, "
                f"beside the person's own trial to trial ({held.scheme()}; EMD has no unit: "
                "a share of the signature's velocity range)"
            ] = held.table()
            if held.likeness:
                tables[
                    "Human-likeness of the avatar in each role against the held-out trials "
                    f"(at most {MAX_UNITS} of its sessions, spread over the folds; distances: "
                    "mean over pairs of trials or sessions)"
                ] = pd.concat(
                    {role: result.table() for role, result in held.likeness.items()}
                ).rename(columns=LIKENESS_HEADERS)
        if self.partners is not None:
            tables["The person and the avatar against their partner's recorded track (mean)"] = (
                self.partners.table()
            )
        return tables

    def plot_trace(self, name: str) -> Figure | None:
        """Plot the person against the avatar, positions over the first `TRACE_SECONDS`.

        With a partner session: the partner as recorded, the person, and the avatar's first
        replay in the person's place. Otherwise the `example`: a held-out trial beside a session
        the avatar built without it played. None when there is neither.
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
        if self.example is None:
            return None
        trial, played = self.example
        times = played.times - played.times[0]
        times = times[times <= min(TRACE_SECONDS, trial.duration)]
        person = np.interp(times, trial.times - trial.times[0], trial.positions)
        return plot_positions(
            times,
            {
                f"{name} ({trial.label}, held out)": person,
                f"avatar of {name} (as {played.roles[1]})": played.positions[1][: times.size],
            },
            f"{name}'s held-out trial and the avatar built without it playing",
        )
