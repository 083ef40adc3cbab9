"""A study's runs' outcomes read back: the completion each person was shown, the refusals.

`read_study_outcomes` reads, for every run under the paths `mirror_avatar.analysis.trials.
read_study_trials` takes, its end and its refusals (`mirror_avatar.lab.export.run_outcomes`):
from a run folder, and from a BIDS dataset's ``sourcedata/<session id>/``, where the export copies
them. A run screened out before its first trial has no trial to export: its refusals are read
from its run folder (the lab's ``--out``). A BIDS subject folder gives none (its dataset's
``sourcedata/`` holds every subject's runs).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from mirror_avatar.analysis.trials import DATASET_FILE, participant_name
from mirror_avatar.lab.export.bids_study import read_study
from mirror_avatar.lab.export.run_outcomes import RunOutcomes, read_outcomes
from mirror_avatar.lab.files import is_session_folder

RunKey = tuple[str, str]
"""A run: its participant (``p003``, or a plain session's id) and its session id."""


def read_study_outcomes(paths: Sequence[Path]) -> dict[RunKey, RunOutcomes]:
    """Read the outcomes of every run under ``paths`` that has any, by participant and session.

    Raises
    ------
    InputError
        A run's ``study.json``, end or refusal that cannot be read.
    """
    found: dict[RunKey, RunOutcomes] = {}
    for folder in (run for path in paths for run in _run_folders(path)):
        outcomes = read_outcomes(folder)
        if outcomes.completion or outcomes.refusals:
            found[(participant_name(read_study(folder), folder.name), folder.name)] = outcomes
    return found


def _run_folders(path: Path) -> list[Path]:
    """Return the run folders a path of `read_study_trials` holds (see the module docstring)."""
    if is_session_folder(path):
        return [path]
    if (path / DATASET_FILE).is_file():
        path = path / "sourcedata"
    elif path.name.startswith("sub-") or not path.is_dir():
        return []
    return sorted(p for p in path.iterdir() if p.is_dir() and is_session_folder(p))
