"""Sets of trials: finding a researcher's trial files and saying which person each belongs to.

A path given is a trial file or a folder searched recursively (a BIDS dataset root included).
Inside folders, files that cannot be read as trials (a session beside the solo trials, a CSV of
something else) are skipped with a note rather than failing the whole folder; a file named
explicitly must be a trial. Files are read within the limits of `mirror_avatar.trial_io`; a
``--group-by`` map, like a sidecar, up to `mirror_avatar.trial_io.MAX_SIDECAR_BYTES`.

Trials are grouped (the person, or style, each belongs to) by one rule (`GROUPINGS`):
``directory`` (the folder a file is in, relative to the folder given: ``sub-01/motion`` and
``sub-02/motion`` stay apart), ``bids`` (the ``sub-`` entity of the file name or a parent
folder), ``file`` (each file its own group), ``none`` (one group), ``pattern:REGEX`` (the first
group of REGEX searched in the file name, or its whole match) or ``map:FILE.csv`` (a table with
columns ``file`` and ``group``).
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from mirror_avatar.errors import InputError
from mirror_avatar.importing import DEFAULT_IMPORT, ImportOptions, excerpt
from mirror_avatar.trial_io import SUPPORTED, read_sidecar_text, read_trial_file
from mirror_avatar.trials import Trial

GROUPINGS = ("directory", "bids", "file", "none", "pattern:REGEX", "map:FILE.csv")
"""The grouping rules a ``--group-by`` names."""

SESSION_SUFFIXES = ("_session.csv", "session.csv", "session.parquet")
"""Names of session files the toolkit writes: not solo trials."""


@dataclass
class TrialSet:
    """Trials read from a researcher's paths, their groups, and what was skipped.

    Attributes
    ----------
    trials
        The trials, each with its ``group`` set.
    notes
        One line per file skipped, naming it and why.
    """

    trials: list[Trial] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def summary(self) -> list[str]:
        """One line per group: its name, how many trials, and the first labels."""
        groups: dict[str, list[str]] = {}
        for trial in self.trials:
            groups.setdefault(trial.group, []).append(trial.label)
        lines = []
        for name, labels in groups.items():
            shown = ", ".join(labels[:4]) + (", ..." if len(labels) > 4 else "")
            lines.append(f"group {name!r}: {len(labels)} trial(s) ({shown})")
        return lines


def read_trial_set(
    paths: Sequence[str | Path],
    group_by: str = "directory",
    options: ImportOptions = DEFAULT_IMPORT,
) -> TrialSet:
    """Read the trials of ``paths`` and group them by ``group_by`` (see the module docstring).

    Raises
    ------
    InputError
        A path that does not exist, a named file that is not a trial, a folder with no trial,
        an unknown grouping, or a trial that the grouping cannot place.
    """
    rule = _grouping(group_by)
    found = TrialSet()
    for path in map(Path, paths):
        if not path.exists():
            raise InputError(path, "no such file or folder")
        if path.is_dir():
            _read_folder(path, rule, options, found)
        else:
            for trial in read_trial_file(path, options):
                found.trials.append(replace(trial, group=rule(trial, path, path.parent)))
    return found


def _read_folder(folder: Path, rule: _Rule, options: ImportOptions, found: TrialSet) -> None:
    files = sorted(
        p
        for p in folder.rglob("*")
        if p.is_file()
        and p.name.lower().endswith(SUPPORTED)
        and not any(part.startswith(".") for part in p.relative_to(folder).parts)
    )
    before, reasons = len(found.trials), []
    for file in files:
        if file.name.endswith(SESSION_SUFFIXES):
            found.notes.append(f"skipped {file}: a session file (read it with evaluate)")
            continue
        try:
            trials = read_trial_file(file, options)
        except InputError as error:
            found.notes.append(f"skipped {file}: {error.problem}")
            reasons.append(f"{file.relative_to(folder)}: {error.problem}")
            continue
        found.trials += [replace(t, group=rule(t, file, folder)) for t in trials]
    if len(found.trials) == before:
        first = f"; {reasons[0]}" if reasons else ""
        raise InputError(folder, f"no readable trial file in it ({len(files)} skipped){first}")


class _Rule:
    """A grouping rule: ``rule(trial, file, root) -> group``."""

    def __call__(self, trial: Trial, file: Path, root: Path) -> str:
        raise NotImplementedError


def _grouping(group_by: str) -> _Rule:
    if group_by.startswith("pattern:"):
        return _Pattern(group_by.removeprefix("pattern:"))
    if group_by.startswith("map:"):
        return _Map(Path(group_by.removeprefix("map:")))
    rules: dict[str, _Rule] = {
        "directory": _Directory(),
        "bids": _Bids(),
        "file": _File(),
        "none": _Everyone(),
    }
    if group_by not in rules:
        raise InputError(
            "--group-by", f"unknown grouping {excerpt(group_by)}; use {', '.join(GROUPINGS)}"
        )
    return rules[group_by]


class _Directory(_Rule):
    def __call__(self, trial: Trial, file: Path, root: Path) -> str:
        if trial.group:
            return trial.group
        parent = file.resolve().parent
        inside = (
            parent.relative_to(root.resolve()) if parent.is_relative_to(root.resolve()) else None
        )
        if inside is None or inside == Path("."):
            return parent.name
        return inside.as_posix()


class _Bids(_Rule):
    def __call__(self, trial: Trial, file: Path, root: Path) -> str:
        for part in (file.name, *reversed(file.parent.parts)):
            match = re.match(r"(sub-[A-Za-z0-9]+)", part)
            if match:
                return match.group(1)
        raise InputError(file, "no BIDS sub- entity in its name or folders: use another --group-by")


class _File(_Rule):
    def __call__(self, trial: Trial, file: Path, root: Path) -> str:
        return trial.label if trial.label != file.stem else file.stem


class _Everyone(_Rule):
    def __call__(self, trial: Trial, file: Path, root: Path) -> str:
        return "all"


class _Pattern(_Rule):
    def __init__(self, pattern: str) -> None:
        try:
            self.pattern = re.compile(pattern)
        except re.error as error:
            raise InputError(
                "--group-by", f"pattern {excerpt(pattern)} is not valid ({error})"
            ) from None

    def __call__(self, trial: Trial, file: Path, root: Path) -> str:
        match = self.pattern.search(file.name)
        if match is None:
            raise InputError(
                file, f"the --group-by pattern {excerpt(self.pattern.pattern)} does not match"
            )
        return match.group(1) if match.groups() else match.group(0)


class _Map(_Rule):
    def __init__(self, table: Path) -> None:
        try:
            rows = list(csv.DictReader(io.StringIO(read_sidecar_text(table))))
        except csv.Error as error:
            raise InputError(
                table, f"the --group-by map is not a valid CSV file ({error})"
            ) from None
        if not rows or not {"file", "group"} <= set(rows[0]):
            raise InputError(table, "the --group-by map needs columns file,group")
        self.groups = {(row["file"] or "").strip(): (row["group"] or "").strip() for row in rows}

    def __call__(self, trial: Trial, file: Path, root: Path) -> str:
        for key in (file.name, file.stem, file.as_posix()):
            if key in self.groups:
                return self.groups[key]
        raise InputError(file, "not in the --group-by map (give its name in column file)")
