"""Sets of trials: finding a researcher's trial files and saying which person each belongs to.

A path given is a trial file or a folder searched recursively (a BIDS dataset root included).
Inside folders, files that cannot be read as trials (a session beside the solo trials, a CSV of
something else) are skipped with a note rather than failing the whole folder; a file named
explicitly must be a trial, and a file reached twice is read once. Files are read within the
limits of `mirror_avatar.files.trial_io`; a ``--group-by`` map, like a sidecar, up to
`mirror_avatar.files.trial_io.MAX_SIDECAR_BYTES`.

A trial's identity is its source, never its base name (`trial_identity`): its label is its file's
path relative to the folder all the paths given share (`common_root`), without the extension
(``p1/trial_00``; the trials of a MATLAB file add ``-k``); a BIDS file keeps its entities
(``sub-01_ses-2_task-mirror_run-3``) and drops the folders that repeat them. Labels are unique
within a set, so analyses, figures and reports can key on them; ``metadata["source"]`` keeps
the path as found.

Trials are grouped (the person, or style, each belongs to) by one rule (`GROUPINGS`):
``directory`` (the folder a file is in, relative to the folder given: ``sub-01/motion`` and
``sub-02/motion`` stay apart; two folders of one name, such as ``a/alice`` and ``b/alice`` given
as two paths, are refused rather than merged into one person), ``bids`` (the ``sub-`` entity of
the file name or a parent folder), ``file`` (each trial its own group, named by its label),
``none`` (one group), ``pattern:REGEX`` (the first group of REGEX searched in the file name, or
its whole match) or ``map:FILE.csv`` (a table with columns ``file`` and ``group``). A map's
``file`` is a path, relative to the map's own folder or as given on the command line (relative
to the working folder, or absolute); a bare file name is accepted only while it names one file
of the set.
"""

from __future__ import annotations

import csv
import io
import os
import re
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.bids.names import folder_repeats_entities, recording_stem
from mirror_avatar.files.importing import DEFAULT_IMPORT, ImportOptions, excerpt
from mirror_avatar.files.trial_files import SUPPORTED, read_trial_file
from mirror_avatar.files.trial_io import read_sidecar_text
from mirror_avatar.files.trials import Trial

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
    """Read the trials of ``paths``, label them by identity and group them by ``group_by``.

    See the module docstring for the labels and the groupings.

    Raises
    ------
    InputError
        A path that does not exist, a named file that is not a trial, a folder with no trial,
        an unknown grouping, or a trial that the grouping cannot place.
    """
    rule = _grouping(group_by)
    given = [Path(path) for path in paths]
    for path in given:
        if not path.exists():
            raise InputError(path, "no such file or folder")
    root = common_root(given)
    found, seen = TrialSet(), set[Path]()
    for path in given:
        if path.is_dir():
            _read_folder(path, root, rule, options, found, seen)
        elif _first_time(path, seen, found):
            found.trials += _identified(
                read_trial_file(path, options), path, root, path.parent, rule
            )
    _make_labels_unique(found.trials, root)
    return found


def common_root(paths: Sequence[Path]) -> Path:
    """Return the deepest folder holding every path (a folder given, or a file's folder)."""
    folders = [os.path.abspath(p if p.is_dir() else p.parent) for p in paths]
    return Path(os.path.commonpath(folders)) if folders else Path.cwd()


def trial_identity(file: Path, root: Path) -> str:
    """Return the identity of ``file``'s trials: its path from ``root``, without the extension.

    The folders of a BIDS file that repeat its entities (``sub-01/ses-2/motion``) are left out:
    the file name holds them. A file outside ``root`` is named by its file name.
    """
    try:
        relative = Path(os.path.abspath(file)).relative_to(root)
    except ValueError:
        relative = Path(file.name)
    folders = [p for p in relative.parent.parts if not folder_repeats_entities(p, file.name)]
    return "/".join([*folders, recording_stem(file.name)])


def _identified(
    trials: list[Trial], file: Path, root: Path, base: Path, rule: _Rule
) -> list[Trial]:
    """Label ``file``'s trials by identity, record their source, and group them."""
    identity = trial_identity(file, root)
    labelled = [
        replace(
            trial,
            label=identity + _trial_suffix(trial, k, len(trials)),
            metadata=trial.metadata | {"source": str(file)},
        )
        for k, trial in enumerate(trials)
    ]
    return [replace(trial, group=rule(trial, file, base)) for trial in labelled]


def _trial_suffix(trial: Trial, k: int, count: int) -> str:
    """Return how a trial's label ends: ``-PLAYER`` (``--columns``), else ``-k`` (from 1).

    A file of one trial without a player adds nothing.
    """
    if player := trial.metadata.get("player"):
        return f"-{player}"
    return f"-{k + 1}" if count > 1 else ""


def _first_time(file: Path, seen: set[Path], found: TrialSet) -> bool:
    """Whether ``file`` is read for the first time (a file reached twice is noted, not read)."""
    resolved = file.resolve()
    if resolved in seen:
        found.notes.append(f"skipped {file}: given more than once")
        return False
    seen.add(resolved)
    return True


def _make_labels_unique(trials: list[Trial], root: Path) -> None:
    """Name trials whose identities still coincide by their whole path (extension included)."""
    counts = Counter(trial.label for trial in trials)
    for k, trial in enumerate(trials):
        if counts[trial.label] > 1:
            source = Path(trial.metadata["source"])
            suffix = trial.label.removeprefix(trial_identity(source, root))
            whole = Path(os.path.abspath(source))
            name = whole.relative_to(root).as_posix() if whole.is_relative_to(root) else str(source)
            trials[k] = replace(trial, label=name + suffix)
    repeated = [label for label, n in Counter(t.label for t in trials).items() if n > 1]
    if repeated:
        raise InputError(None, f"two trials are both {excerpt(repeated[0])}")


def _read_folder(
    folder: Path, root: Path, rule: _Rule, options: ImportOptions, found: TrialSet, seen: set[Path]
) -> None:
    files = sorted(
        p
        for p in folder.rglob("*")
        if p.is_file()
        and p.name.lower().endswith(SUPPORTED)
        and not any(part.startswith(".") for part in p.relative_to(folder).parts)
    )
    before, reasons, repeated = len(found.trials), [], 0
    for file in files:
        if file.name.endswith(SESSION_SUFFIXES):
            found.notes.append(f"skipped {file}: a session file (read it with evaluate)")
            continue
        if not _first_time(file, seen, found):
            repeated += 1
            continue
        try:
            trials = read_trial_file(file, options)
        except InputError as error:
            found.notes.append(f"skipped {file}: {error.problem}")
            reasons.append(f"{file.relative_to(folder)}: {error.problem}")
            continue
        found.trials += _identified(trials, file, root, folder, rule)
    if len(found.trials) == before and not repeated:
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
    """The folder a file is in, relative to the folder given: one group is one folder."""

    def __init__(self) -> None:
        self.folders: dict[str, tuple[Path, Path]] = {}

    def __call__(self, trial: Trial, file: Path, root: Path) -> str:
        if trial.group:
            return trial.group
        parent = file.resolve().parent
        inside = (
            parent.relative_to(root.resolve()) if parent.is_relative_to(root.resolve()) else None
        )
        group = parent.name if inside is None or inside == Path(".") else inside.as_posix()
        self._check_one_folder(group, parent, file.parent)
        return group

    def _check_one_folder(self, group: str, folder: Path, shown: Path) -> None:
        """Refuse a second folder (resolved ``folder``, given as ``shown``) named ``group``."""
        first, first_shown = self.folders.setdefault(group, (folder, shown))
        if first != folder:
            raise InputError(
                None,
                f"{first_shown} and {shown} would both be group {excerpt(group)} (one person): "
                "rename one folder, or say whose trials are whose with --group-by map:FILE.csv",
            )


class _Bids(_Rule):
    def __call__(self, trial: Trial, file: Path, root: Path) -> str:
        for part in (file.name, *reversed(file.parent.parts)):
            match = re.match(r"(sub-[A-Za-z0-9]+)", part)
            if match:
                return match.group(1)
        raise InputError(file, "no BIDS sub- entity in its name or folders: use another --group-by")


class _File(_Rule):
    def __call__(self, trial: Trial, file: Path, root: Path) -> str:
        return trial.label


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
    """Groups from a table of paths (relative to the table's folder or to the working folder)."""

    def __init__(self, table: Path) -> None:
        try:
            rows = list(csv.DictReader(io.StringIO(read_sidecar_text(table))))
        except csv.Error as error:
            raise InputError(
                table, f"the --group-by map is not a valid CSV file ({error})"
            ) from None
        if not rows or not {"file", "group"} <= set(rows[0]):
            raise InputError(table, "the --group-by map needs columns file,group")
        self.table = table
        self.by_name: dict[str, str] = {}
        self.by_path: dict[Path, tuple[str, str]] = {}
        for row in rows:
            key, group = (row["file"] or "").strip(), (row["group"] or "").strip()
            self.by_name[key] = group
            for base in (table.parent, Path.cwd()):
                self._add_path((base / key).resolve(), key, group)
        self.named: dict[str, Path] = {}

    def _add_path(self, path: Path, key: str, group: str) -> None:
        other_key, other = self.by_path.setdefault(path, (key, group))
        if other != group:
            raise InputError(
                self.table,
                f"rows {excerpt(other_key)} and {excerpt(key)} name one file with two groups "
                f"({excerpt(other)} and {excerpt(group)})",
            )

    def __call__(self, trial: Trial, file: Path, root: Path) -> str:
        target = file.resolve()
        if target in self.by_path:
            return self.by_path[target][1]
        for key in (file.name, file.stem):
            if key in self.by_name:
                first = self.named.setdefault(key, target)
                if first != target:
                    raise InputError(
                        self.table,
                        f"row {excerpt(key)} of the --group-by map names both {first} and "
                        f"{target}: give paths relative to the map's folder or as given on the "
                        "command line",
                    )
                return self.by_name[key]
        raise InputError(
            file,
            f"not in the --group-by map {self.table} (column file: the path relative to the "
            "map's folder, or as given on the command line)",
        )
