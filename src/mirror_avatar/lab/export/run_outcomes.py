"""How a study run ended for its people: the completion their end page showed, the refusals.

A participant's run of a protocol (`mirror_avatar.lab.running.study`) writes `ENDED_FILE` once
its last trial, and that trial's questions, are over (`write_ended`): when (``ended_utc``, UTC
ISO 8601), the protocol's completion (``{"code", "url"}``, null when it has none) and ``shown``,
the labels of the people whose pages were connected then and not refused: each of those pages
shows the completion on its end page. A person screened out
(`mirror_avatar.lab.running.screening.record_refusal`) has ``refusal-<label>.json``: the
reason, when (``utc``) and what was measured. `read_outcomes` reads both back, for the BIDS
export's ``participants.tsv`` (`mirror_avatar.lab.export.bids`) and the study table
(`mirror_avatar.analysis.table`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import write_atomic_json
from mirror_avatar.files.trial_io import read_sidecar_text
from mirror_avatar.files.user_files import parse_json
from mirror_avatar.lab.files import ENDED_FILE, REFUSAL_PATTERN


@dataclass(frozen=True)
class RunOutcomes:
    """What a run's people were given at its end, and who was screened out.

    Attributes
    ----------
    completion
        By label, what each person's end page showed: the completion code, or the link back
        when the protocol gives only a link.
    refusals
        By label, why each person screened out was refused.
    """

    completion: dict[str, str] = field(default_factory=dict)
    refusals: dict[str, str] = field(default_factory=dict)


def write_ended(
    directory: Path, completion: dict[str, str | None] | None, shown: list[str]
) -> None:
    """Write `ENDED_FILE` in a run's folder (blocking; the module docstring says what it holds)."""
    ended = {"ended_utc": datetime.now(UTC).isoformat(), "completion": completion, "shown": shown}
    write_atomic_json(directory / ENDED_FILE, ended)


def read_outcomes(directory: Path) -> RunOutcomes:
    """Read a run folder's `ENDED_FILE` and refusals; empty outcomes where there are none.

    Raises
    ------
    InputError
        A file that is not a JSON object, an ending whose ``shown`` is not a list of labels, a
        refusal without its reason.
    """
    return RunOutcomes(_completion(directory / ENDED_FILE), _refusals(directory))


def _completion(path: Path) -> dict[str, str]:
    if not path.is_file():
        return {}
    ended = _object(path)
    completion = ended.get("completion")
    given = completion if isinstance(completion, dict) else {}
    shown = given.get("code") or given.get("url")
    labels = ended.get("shown")
    if not isinstance(labels, list) or not all(isinstance(label, str) for label in labels):
        raise InputError(path, "shown is not a list of the labels shown the completion")
    return {} if not isinstance(shown, str) else dict.fromkeys(labels, shown)


def _refusals(directory: Path) -> dict[str, str]:
    refusals: dict[str, str] = {}
    for path in sorted(directory.glob(REFUSAL_PATTERN)):
        refusal = _object(path)
        label, reason = refusal.get("label"), refusal.get("reason")
        if not isinstance(label, str) or not isinstance(reason, str):
            raise InputError(path, "not a refusal: no label or no reason")
        refusals[label] = reason
    return refusals


def _object(path: Path) -> dict[str, Any]:
    value = parse_json(read_sidecar_text(path), path)
    if not isinstance(value, dict):
        raise InputError(path, "not a JSON object")
    return value
