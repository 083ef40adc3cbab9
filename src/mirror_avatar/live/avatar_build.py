"""A participant's avatar built on the live server from the solo trials they just recorded.

The page's "Build my avatar" asks for it (`mirror_avatar.live.messages.BuildRequest`): the
participant's solo trial files in their folder (``P_solo_*.csv``, the person's own trial of each
solo recording) are read, `mirror_avatar.experiments.personal_avatar.create_avatar` builds and
validates the avatar (with the default partners), and it is written beside them as
``P_avatar.npz`` with its card ``P_avatar.html``. The server then plays the connection's trials
with it, and the page shows the card's verdict and links the card (`describe_avatar`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from mirror_avatar import __version__
from mirror_avatar.common.errors import InputError
from mirror_avatar.experiments.avatar_proof import MIN_TRIALS_TO_HOLD_OUT
from mirror_avatar.experiments.personal_avatar import (
    create_avatar,
    default_partners,
    save_avatar,
)
from mirror_avatar.files.trial_files import read_trial
from mirror_avatar.files.user_files import read_text
from mirror_avatar.training.avatar import load_avatar

MAX_CARD_BYTES = 32 * 2**20
"""Largest avatar card sent to the page (bytes; **choice**: a card with its figures is well
under a few MiB)."""

MIN_SOLO_TRIALS = 2
"""Fewest solo trials a build starts from (**choice**: cross-validation needs two)."""


def solo_trial_files(folder: Path, participant: str) -> list[Path]:
    """List the participant's recorded solo trials (their ``time,position`` files), oldest first.

    A trial's session and input-log files (``_session.csv``, ``_inputs.csv``) are not trials.
    """
    return sorted(
        path
        for path in folder.glob(f"{participant}_solo_*.csv")
        if not path.name.endswith(("_session.csv", "_inputs.csv"))
    )


def build_readiness(count: int) -> dict[str, Any]:
    """Say what ``count`` recorded solo trials allow, before "Build my avatar" is pressed.

    Parameters
    ----------
    count
        The participant's recorded solo trials (`solo_trial_files`).

    Returns
    -------
    dict
        ``solo_trials`` (the count), ``ready`` (at least `MIN_SOLO_TRIALS`, so a build can
        start) and ``hint``, a sentence for the page: how many more trials a build needs, and
        whether the avatar will be checked against a held-out trial of the person
        (`MIN_TRIALS_TO_HOLD_OUT` or more) or not.
    """
    recorded = f"{count} solo trial{'s' * (count != 1)} recorded"
    check = f"{MIN_TRIALS_TO_HOLD_OUT} or more let it be checked against you"
    if count < MIN_SOLO_TRIALS:
        hint = f"{recorded}: record {MIN_SOLO_TRIALS - count} more to build your avatar ({check})"
    elif count < MIN_TRIALS_TO_HOLD_OUT:
        hint = (
            f"{recorded}: your avatar can be built, but it will not be checked against you "
            f"({check})"
        )
    else:
        hint = f"{recorded}: enough to build your avatar and check it against a held-out trial"
    return {"solo_trials": count, "ready": count >= MIN_SOLO_TRIALS, "hint": hint}


def build_avatar(
    folder: Path,
    participant: str,
    sessions: tuple[int, int, int],
    progress: Callable[[str], None],
    seed: int = 0,
) -> Path:
    """Build, validate and save ``participant``'s avatar from their solo trials in ``folder``.

    Parameters
    ----------
    folder
        The participant's recording folder.
    participant
        Their id (the avatar's name).
    sessions
        Training sessions per role, validation sessions per partner, baseline sessions.
    progress
        Called with each stage's name as it begins.
    seed
        Seeds the build.

    Returns
    -------
    pathlib.Path
        The avatar file (its card is beside it, ``.html``).

    Raises
    ------
    InputError
        Fewer than `MIN_SOLO_TRIALS` solo trials, or trials the generator cannot be fitted on.
    """
    files = solo_trial_files(folder, participant)
    if len(files) < MIN_SOLO_TRIALS:
        raise InputError(
            participant, f"play at least {MIN_SOLO_TRIALS} solo trials first ({len(files)} so far)"
        )
    trials = [read_trial(path) for path in files]
    progress("preparing the partners")
    partners = default_partners(seed)
    n_train, n_validation, n_baseline = sessions
    avatar, card = create_avatar(
        trials, participant, partners, n_train, n_validation, n_baseline, seed, progress=progress
    )
    path = folder / f"{participant}_avatar.npz"
    save_avatar(avatar, card, path, {"version": __version__, "seed": seed})
    return path


def describe_avatar(path: Path) -> dict[str, str]:
    """Return what the page shows of a built avatar: its card's ``verdict`` and the ``card`` (HTML).

    The card travels in the message so that the page links it without the server serving the
    participant's folder. Both files are read by the checked readers (the card at most
    `MAX_CARD_BYTES`); the server calls this in a worker thread.

    Raises
    ------
    InputError
        An avatar or card that cannot be read (missing, not a regular file, too large).
    """
    return {
        "verdict": str(load_avatar(path).summary.get("verdict", "")),
        "card": read_text(path.with_suffix(".html"), MAX_CARD_BYTES),
    }
