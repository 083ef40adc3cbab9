r"""Writing BIDS-Motion files: values, tables and a single trial's recording.

Values are written exactly (``repr``), a missing one as ``n/a``; TSV tables have a header and
cells on one line, text kept whole: a tab, a line break or a backslash in it is written as in a
string literal (``\t``, ``\n``, ``\r``, ``\\``) and read back by `cell_text`. Every file is
written atomically (`mirror_avatar.files.atomic`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import write_atomic_json, write_atomic_text
from mirror_avatar.files.bids.names import MISSING, MOTION_SUFFIX, entities, recording_stem
from mirror_avatar.files.trials import Trial

Array = NDArray[np.float64]

DEFAULT_TASK = "mirror"
"""``TaskName`` of a trial written to a file name without a ``task-`` entity."""


def tsv_values(rows: Array) -> str:
    """Rows of numbers as headerless TSV: each value exactly (``repr``), NaN as ``n/a``."""
    return "".join(
        "\t".join(MISSING if math.isnan(v) else repr(v) for v in row) + "\n"
        for row in rows.tolist()
    )


TSV_ESCAPES = {"\\": "\\\\", "\t": "\\t", "\n": "\\n", "\r": "\\r"}
"""How a TSV cell writes what would end it or its row: a backslash, a tab and the line breaks
as in a string literal, so that `cell_text` reads back the text as given."""

_ESCAPED = re.compile(r"[\\\t\n\r]")
_ESCAPE = re.compile(r"\\([\\tnr])")
_UNESCAPES = {escape[1]: character for character, escape in TSV_ESCAPES.items()}


def tsv_cell(text: str) -> str:
    """Write ``text`` as one TSV cell, every character kept (`TSV_ESCAPES`)."""
    return _ESCAPED.sub(lambda found: TSV_ESCAPES[found.group()], text)


def cell_text(cell: str) -> str:
    """Read back the text `tsv_cell` wrote; a backslash before any other character stays."""
    return _ESCAPE.sub(lambda found: _UNESCAPES[found.group(1)], cell)


def tsv_table(columns: Iterable[str], rows: Iterable[dict[str, str]]) -> str:
    """Write a TSV table with a header; cells missing from a row or empty are ``n/a``."""
    columns = list(columns)
    lines = ["\t".join(columns)]
    lines += ["\t".join(tsv_cell(row.get(c, MISSING)) or MISSING for c in columns) for row in rows]
    return "\n".join(lines) + "\n"


def write_bids_motion(trial: Trial, path: str | Path) -> None:
    """Write a uniformly sampled ``trial`` as ``*_motion.tsv`` + ``*_motion.json``.

    ``TaskName`` is the file name's ``task-`` entity (`DEFAULT_TASK` without one), so that the
    name and the sidecar agree; the trial's label is not written.
    """
    path = Path(path)
    if not path.name.endswith(MOTION_SUFFIX):
        raise InputError(path, f"BIDS-Motion file names end in {MOTION_SUFFIX}")
    steps = np.diff(trial.times)
    if not np.allclose(steps, steps[0], rtol=1e-9, atol=0):
        raise InputError(path, "BIDS-Motion needs uniform sampling; resample the trial first")
    sidecar = {
        "TaskName": entities(path.name).get("task", DEFAULT_TASK),
        "SamplingFrequency": 1.0 / float(steps.mean()),
        "MotionChannelCount": 1,
    }
    write_atomic_text(path, tsv_values(trial.positions[:, None]))
    write_atomic_json(path.with_name(f"{recording_stem(path.name)}_motion.json"), sidecar)
