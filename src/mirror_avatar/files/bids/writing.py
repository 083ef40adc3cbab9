"""Writing BIDS-Motion files: values, tables and a single trial's recording.

Values are written exactly (``repr``), a missing one as ``n/a``; TSV tables have a header and
cells on one line. Every file is written atomically (`mirror_avatar.files.atomic`).
"""

from __future__ import annotations

import math
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


def one_line(text: str) -> str:
    """``text`` without tabs or line breaks, so that it fits one TSV cell."""
    return " ".join(text.split())


def tsv_table(columns: Iterable[str], rows: Iterable[dict[str, str]]) -> str:
    """Write a TSV table with a header; cells missing from a row are ``n/a``."""
    columns = list(columns)
    lines = ["\t".join(columns)]
    lines += ["\t".join(one_line(row.get(c, MISSING)) or MISSING for c in columns) for row in rows]
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
