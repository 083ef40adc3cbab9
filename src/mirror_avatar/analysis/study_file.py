"""A study table read back for its statistics: the long table and its data dictionary.

The table (``study.csv`` or ``study.parquet``, written by ``mirror-avatar study table``) has a
row per trial and player; its data dictionary (``study.json``, BIDS style) gives each column's
"Description", "Units", "Levels" and "Role" (``identifier``, ``design``, ``measure``,
``p_value`` or ``answer``). The statistics need the columns ``participant``, ``condition`` and
``position``, and at least one measure; a table without a dictionary has every numeric column
outside the known design, answer and p-value (``*_p_value``) columns as a measure.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from mirror_avatar.analysis.dictionary import (
    DESIGN_COLUMNS,
    GUESS_COLUMNS,
    PAGE_COLUMNS,
    PANEL_PREFIX,
    RUN_COLUMNS,
    column_label,
)
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import csv_cells
from mirror_avatar.files.trial_io import MAX_SIDECAR_BYTES
from mirror_avatar.files.user_files import parse_json, read_text

TABLE_NAMES = ("study.csv", "study.parquet")
"""The table's file names in a folder, in the order they are looked for."""

TEXT_COLUMNS = (
    "participant", "person", "player_kind", "condition", "partners", "partner_kind", "guess_kind",
    "completion_code", "refusal",
)  # fmt: skip
"""Columns read as text whatever they hold (a participant "001" stays "001"), with every panel
identifier's (``panel_<name>``)."""

NOT_MEASURES = (*DESIGN_COLUMNS, *RUN_COLUMNS, *PAGE_COLUMNS, *GUESS_COLUMNS)
"""The columns that are never a measure: the study table's identifiers, design, runs' outcomes,
pages and guesses (`mirror_avatar.analysis.dictionary`), besides the panel identifiers."""

REQUIRED_COLUMNS = ("participant", "condition", "position")
"""The columns the statistics cannot do without."""


@dataclass(frozen=True)
class StudyTable:
    """A study's long table with its data dictionary.

    Parameters
    ----------
    rows
        One row per trial and player.
    dictionary
        Column name -> its description (``Description``, ``Units``, ``Levels``, ``Role``);
        empty when the table came without one.
    source
        The file the rows were read from.
    """

    rows: pd.DataFrame
    dictionary: dict[str, dict[str, Any]]
    source: Path

    @property
    def measures(self) -> list[str]:
        """The numeric measure columns: Role "measure" in the dictionary, else not design."""
        if self.dictionary:
            return [name for name in self._declared_measures() if self._numeric(name)]
        return [
            name
            for name in self.rows.columns
            if name not in NOT_MEASURES
            and not name.startswith(("answer_", PANEL_PREFIX))
            and not name.endswith("_p_value")
            and self._numeric(name)
            and not pd.api.types.is_bool_dtype(self.rows[name])
        ]

    @property
    def rated_answers(self) -> list[str]:
        """The answers given as numbers (a rating): Role "answer" (or ``answer_...``), numeric."""
        if self.dictionary:
            declared = [n for n, e in self.dictionary.items() if e.get("Role") == "answer"]
        else:
            declared = [n for n in self.rows.columns if n.startswith("answer_")]
        return [
            name
            for name in declared
            if name in self.rows
            and self._numeric(name)
            and not pd.api.types.is_bool_dtype(self.rows[name])
        ]

    @property
    def outcomes(self) -> list[str]:
        """Every column compared between conditions: the measures, then the rated answers."""
        return self.measures + self.rated_answers

    @property
    def skipped_measures(self) -> list[str]:
        """The dictionary's measures that hold no numbers (a leader's label): not averaged."""
        return [name for name in self._declared_measures() if not self._numeric(name)]

    def _declared_measures(self) -> list[str]:
        return [
            name
            for name, entry in self.dictionary.items()
            if entry.get("Role") == "measure" and name in self.rows
        ]

    def _numeric(self, name: str) -> bool:
        return pd.api.types.is_numeric_dtype(self.rows[name])

    def units(self, column: str) -> str:
        """Return the column's units from the dictionary, or "" when it has none."""
        return str(self.dictionary.get(column, {}).get("Units", ""))

    def label(self, column: str) -> str:
        """Name a column in words (`mirror_avatar.analysis.dictionary.column_label`)."""
        return column_label(column)

    def conditions(self) -> list[str]:
        """List the conditions in the dictionary's order of levels, then as they appear."""
        levels = self.dictionary.get("condition", {}).get("Levels", {})
        present = list(dict.fromkeys(self.rows["condition"].dropna()))
        return [c for c in levels if c in present] + [c for c in present if c not in levels]


def read_study_table(path: str | Path) -> StudyTable:
    """Read a study table: a folder holding ``study.csv`` (or ``study.parquet``), or the file.

    The dictionary is ``study.json`` in the folder, or the file's name with ``.json``.

    Raises
    ------
    InputError
        No table at ``path``, a file that is not a CSV or Parquet table, a dictionary that
        cannot be read (`mirror_avatar.files.user_files`: not a regular file, too large, not
        JSON, nested too deeply), a required column missing, no condition, or no
        measure column.
    """
    path = Path(path)
    file = _table_file(path)
    try:
        rows = _read_rows(file)
    except (ValueError, OSError) as error:
        raise InputError(file, f"cannot be read as a table ({error})") from None
    dictionary = _read_dictionary(file.with_suffix(".json"))
    missing = [name for name in REQUIRED_COLUMNS if name not in rows]
    if missing:
        raise InputError(
            file,
            f"no {', '.join(missing)} column: give the table `mirror-avatar study table` writes",
        )
    table = StudyTable(rows=rows, dictionary=dictionary, source=file)
    if not table.conditions():
        raise InputError(file, "no row has a condition: the statistics compare conditions")
    if not table.measures:
        raise InputError(file, 'no measure column (Role "measure" in its study.json)')
    return table


def _table_file(path: Path) -> Path:
    if path.is_dir():
        found = [path / name for name in TABLE_NAMES if (path / name).is_file()]
        if not found:
            names = " or ".join(TABLE_NAMES)
            problem = f"no {names} in it: give the folder `study table --out` wrote, or a table"
            raise InputError(path, problem)
        return found[0]
    if not path.is_file():
        raise InputError(path, "no such file or folder: give a study table (folder or .csv)")
    if path.suffix.lower() not in (".csv", ".parquet"):
        raise InputError(path, "is not a .csv or .parquet table")
    return path


def _read_rows(file: Path) -> pd.DataFrame:
    if file.suffix.lower() == ".parquet":
        return pd.read_parquet(file)
    header = pd.read_csv(file, nrows=0).columns
    text = [c for c in header if c in TEXT_COLUMNS or c.startswith(PANEL_PREFIX)]
    return csv_cells(pd.read_csv(file, dtype=dict.fromkeys(text, str)))


def _read_dictionary(file: Path) -> dict[str, dict[str, Any]]:
    if not file.is_file():
        return {}
    dictionary = parse_json(read_text(file, MAX_SIDECAR_BYTES), file, finite=False)
    if not isinstance(dictionary, dict) or not all(
        isinstance(v, dict) for v in dictionary.values()
    ):
        raise InputError(file, "is not a data dictionary (an object of column -> object)")
    return dictionary
