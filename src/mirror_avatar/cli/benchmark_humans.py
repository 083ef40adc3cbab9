"""The recorded human followers of ``mirror-avatar benchmark --humans``, with their leaders.

A human follower's recording is a session of two players, one whose role is ``leader`` and one
whose role is ``follower`` (the person): the toolkit's session files and lab runs, BIDS-Motion
lab exports, or any table of the two players' positions read with ``--columns`` (leader first:
a session without roles takes the default leader, follower). A lab recording whose follower's
slot is an avatar is refused. Files and folders are read as ``evaluate`` reads them
(`mirror_avatar.cli.evaluate.find_sessions`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from mirror_avatar.cli.evaluate import find_sessions, session_names
from mirror_avatar.cli.reading import SessionReading
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trial_record import lab_trial_record
from mirror_avatar.files.trials import DEFAULT_RATE, Trial, make_trial
from mirror_avatar.sessions.session import Session

OPTION = "--humans"
"""The option naming the recordings, quoted in error lines."""


@dataclass(frozen=True)
class HumanFollowers:
    """The recordings read: each leader and the person following it, at 100 Hz, in order.

    Attributes
    ----------
    leaders, followers
        ``followers[i]`` followed ``leaders[i]``; both labelled by the recording's path.
    notes
        How files were read, and the files in folders skipped (one line each).
    """

    leaders: list[Trial]
    followers: list[Trial]
    notes: list[str]


def read_human_followers(paths: Sequence[str], reading: SessionReading) -> HumanFollowers:
    """Read the recordings of people following a leader (see the module docstring).

    Raises
    ------
    InputError
        ``--humans: FILE: problem`` for a missing or unreadable file, or a recording that is
        not one leader and one follower.
    """
    try:
        found, notes = find_sessions(tuple(Path(path) for path in paths), reading)
    except InputError as error:
        raise InputError(OPTION, str(error)) from None
    leaders: list[Trial] = []
    followers: list[Trial] = []
    for name, (path, session) in zip(session_names([p for p, _ in found]), found, strict=True):
        leader, follower = _roles(path, session)
        for trials, player in ((leaders, leader), (followers, follower)):
            trial = make_trial(
                session.times, session.positions[player], source=str(path), label=name,
                group=path.parent.name,
            )  # fmt: skip
            trials.append(trial.resampled(DEFAULT_RATE))
    return HumanFollowers(leaders, followers, notes)


def _roles(path: Path, session: Session) -> tuple[int, int]:
    """Return the leader's and the follower's player numbers, refusing any other recording."""
    roles = list(session.roles)
    if sorted(roles) != ["follower", "leader"]:
        raise InputError(
            OPTION, f"{path}: players with roles {', '.join(roles)}; a human follower's recording "
            "holds one leader and one follower (--columns time=T,leader=L,follower=F for a "
            "table of their positions)",
        )  # fmt: skip
    leader, follower = roles.index("leader"), roles.index("follower")
    record = lab_trial_record(session.metadata, path)
    if (
        record is not None
        and follower < len(record.slots)
        and record.slots[follower].kind == "avatar"
    ):
        raise InputError(
            OPTION, f"{path}: its follower {session.labels[follower]!r} is an avatar (the lab "
            "slot's kind), not a person",
        )  # fmt: skip
    return leader, follower
