"""BIDS file names: entities, labels, and the identity of a recording.

A BIDS file name is ``key-value`` entities joined by ``_`` then a suffix and an extension
(``sub-01_ses-2_task-mirror_run-3_motion.tsv``); keys and values are letters and digits. A
recording's identity is its entities (the name without suffix and extension): unique within a
dataset by the specification, so runs, sessions and tasks of one subject stay apart.
"""

from __future__ import annotations

import os
import re

from mirror_avatar.common.errors import InputError

MOTION_SUFFIX = "_motion.tsv"
"""How a BIDS-Motion recording's file name ends."""

MISSING = "n/a"
"""How BIDS writes a missing value."""

ENTITY = re.compile(r"([A-Za-z0-9]+)-([A-Za-z0-9]+)")
"""One ``key-value`` entity."""

DATATYPE = "motion"
"""The folder of BIDS-Motion recordings inside ``sub-<label>[/ses-<label>]``."""


def bids_label(text: str, source: str | os.PathLike[str] | None = None) -> str:
    """Return ``text`` as a BIDS label: its letters and digits, other characters removed.

    Raises
    ------
    InputError
        If nothing is left (naming ``source``).
    """
    label = re.sub(r"[^A-Za-z0-9]", "", text)
    if not label:
        raise InputError(source, f"{text!r} has no letter or digit to make a BIDS label")
    return label


def recording_stem(name: str) -> str:
    """Return a BIDS-Motion file name without ``_motion.tsv`` (other names: their extension).

    ``sub-01_run-2_motion.tsv`` gives ``sub-01_run-2``; ``trial_00.csv`` gives ``trial_00``.
    """
    if name.endswith(MOTION_SUFFIX):
        return name[: -len(MOTION_SUFFIX)]
    return name.rsplit(".", 1)[0] if "." in name else name


def entities(name: str) -> dict[str, str]:
    """Return the entities of a BIDS file name, in order (empty if it has no ``sub-`` first).

    >>> entities("sub-01_ses-2_task-mirror_run-3_motion.tsv")
    {'sub': '01', 'ses': '2', 'task': 'mirror', 'run': '3'}
    """
    found: dict[str, str] = {}
    for part in recording_stem(name).split("_"):
        match = ENTITY.fullmatch(part)
        if match is None:
            break
        found[match.group(1)] = match.group(2)
    return found if next(iter(found), None) == "sub" else {}


def folder_repeats_entities(folder: str, name: str) -> bool:
    """Whether ``folder`` (one path part) only repeats what the file ``name`` already says.

    The folders of a BIDS dataset (``sub-01``, ``ses-2``, ``motion``) are named after the
    entities and the datatype of the files they hold.
    """
    found = entities(name)
    if not found:
        return False
    match = ENTITY.fullmatch(folder)
    if match is not None:
        return found.get(match.group(1)) == match.group(2)
    return folder == DATATYPE


def channel_names(label: str, own: bool) -> tuple[str, str]:
    """Names of a player's position and velocity channels in a lab export's recording.

    The participant's own are ``position`` and ``velocity`` (read as their solo trial); every
    other player's carry its label: ``position_<label>``, ``velocity_<label>``.
    """
    suffix = "" if own else f"_{label}"
    return f"position{suffix}", f"velocity{suffix}"
