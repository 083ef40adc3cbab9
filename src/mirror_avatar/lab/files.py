"""The names of a lab session's files in its folder.

A session's folder holds ``plan.json`` (the plan as created), ``study.json`` in a study
session (`mirror_avatar.lab.running.study`) and, for trial n, ``trial-NN_session.csv`` with its
``.json`` sidecar, ``trial-NN_inputs.csv`` (`mirror_avatar.realtime.trial.TickLog`) and, after
questions, ``trial-NN_answers.json``; a study run also holds ``ended.json`` once its last trial
is played and ``refusal-<label>.json`` for each person screened out. The server, the study
runner and the BIDS export all name them here.
"""

from __future__ import annotations

from pathlib import Path

PLAN_FILE = "plan.json"
"""The session's plan, written when the session is created."""

STUDY_FILE = "study.json"
"""A study session's schedule: the protocol's seed and source, the participant, the order run."""

ENDED_FILE = "ended.json"
"""A study run's end: when, the completion code or link, and whose pages were shown it."""

REFUSAL_PATTERN = "refusal-*.json"
"""Glob of the refusals of a study run's people, one file each (`refusal_file`)."""

SESSION_SUFFIX = "_session.csv"
"""How a trial's recording is named after its stem."""

INPUTS_SUFFIX = "_inputs.csv"
"""How a trial's per-sample clock and input log is named after its stem."""

ANSWERS_SUFFIX = "_answers.json"
"""How the answers given after a trial are named after its stem."""

TRIAL_PATTERN = f"trial-*{SESSION_SUFFIX}"
"""Glob of the trials' recordings in a session's folder."""

RECORD_PATTERN = TRIAL_PATTERN.replace(".csv", ".json")
"""Glob of the trials' sidecars (their records) in a session's folder."""


def trial_stem(directory: Path, n: int) -> Path:
    """Path of trial n's files without their suffixes: ``directory/trial-NN``."""
    return directory / f"trial-{n:02d}"


def trial_file(directory: Path, n: int, suffix: str) -> Path:
    """Path of trial n's file named with ``suffix``: ``directory/trial-NN<suffix>``."""
    stem = trial_stem(directory, n)
    return stem.with_name(stem.name + suffix)


def refusal_file(directory: Path, label: str) -> Path:
    """Path of the refusal of the person labelled ``label``: ``directory/refusal-<label>.json``."""
    return directory / REFUSAL_PATTERN.replace("*", label)


def companion(session_csv: Path, suffix: str) -> Path:
    """Return the file of the same trial as ``session_csv`` named with ``suffix``."""
    return session_csv.with_name(session_csv.name.removesuffix(SESSION_SUFFIX) + suffix)


def is_session_folder(path: Path) -> bool:
    """Whether ``path`` is a lab session's folder (it holds a plan or a study schedule)."""
    return (path / PLAN_FILE).exists() or (path / STUDY_FILE).exists()
