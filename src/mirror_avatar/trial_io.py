"""Reading and writing trial files.

Formats: CSV with header ``time,position`` (the exchange format; extra columns are ignored),
and the MATLAB struct format of the bundled data (a 1xK struct array with fields ``x`` and
``v``). Readers do not resample: irregular timestamps are kept (call ``trial.resampled``).
Every reader validates its input and raises `InputError` with one line naming the file
and the problem.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path

import numpy as np
import scipy.io

from mirror_avatar.atomic import atomic_path, write_atomic_json, write_atomic_text
from mirror_avatar.errors import InputError
from mirror_avatar.trials import Trial, make_trial


def read_mat_struct(
    path: str | Path, duration: float, variable: str | None = None, group: str = ""
) -> list[Trial]:
    """Read every trial of a MATLAB struct array with a position field ``x``.

    The bundled format has no timestamps: the samples are spread evenly over ``duration``.

    Parameters
    ----------
    path
        A MATLAB v5 ``.mat`` file.
    duration
        Time the samples of each trial span (s).
    variable
        The struct variable to read; by default the only non-private variable in the file.
    group
        Group given to every trial read.

    Returns
    -------
    list of Trial
        One trial per struct element, labelled ``"<stem>-<k>"`` (k from 1), with
        ``metadata["index"] = k - 1``.
    """
    path = Path(path)
    try:
        contents = scipy.io.loadmat(path)
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except Exception as error:  # scipy raises many types for corrupt files
        raise InputError(path, f"not a readable MATLAB file ({type(error).__name__})") from None
    names = [name for name in contents if not name.startswith("__")]
    if variable is None:
        if len(names) != 1:
            raise InputError(path, f"expected one variable, found {len(names)}: {names}")
        variable = names[0]
    if variable not in contents:
        raise InputError(path, f"no variable {variable!r}; it has {names}")
    struct = np.asarray(contents[variable])
    if struct.dtype.names is None or "x" not in struct.dtype.names:
        raise InputError(path, f"variable {variable!r} is not a struct array with a field 'x'")
    trials = []
    for k, element in enumerate(struct.ravel()):
        positions = np.asarray(element["x"], dtype=np.float64).ravel()
        times = np.linspace(0.0, duration, positions.size)
        trials.append(
            make_trial(
                times,
                positions,
                source=f"{path}[{k}]",
                label=f"{path.stem}-{k + 1}",
                group=group,
                metadata={"index": k},
            )
        )
    return trials


def write_mat_struct(trials: list[Trial], path: str | Path, variable: str) -> None:
    """Write trials as a MATLAB v5 1xK struct array with fields ``x`` and ``v`` (column vectors).

    Like the bundled format, timestamps are not stored; `read_mat_struct` spreads the samples
    evenly over the duration it is given. ``v`` is `Trial.velocity` (units/s).
    """
    struct = np.empty((1, len(trials)), dtype=[("x", object), ("v", object)])
    for k, trial in enumerate(trials):
        struct[0, k] = (trial.positions[:, None], trial.velocity()[:, None])
    with atomic_path(path) as temporary, temporary.open("wb") as handle:
        scipy.io.savemat(handle, {variable: struct})


CSV_COLUMNS = ("time", "position")
MAT_DURATION = 60.0
"""Seconds spanned by each trial of a ``.mat`` file read through `read_trial` (**choice**)."""
SUPPORTED = (".csv", ".mat", ".parquet", "_motion.tsv")


def _read_text(path: Path) -> str:
    if not path.is_file():
        raise InputError(path, "no such file")
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(path, "not a text file") from None


def read_csv_trial(path: str | Path) -> Trial:
    """Read a CSV trial with header ``time,position`` (s, normalised units).

    Raises
    ------
    InputError
        Empty file, missing column (naming the columns found), a non-numeric value (naming
        the row), or any problem `make_trial` finds.
    """
    path = Path(path)
    rows = list(csv.reader(io.StringIO(_read_text(path))))
    rows = [[cell.strip() for cell in row] for row in rows if any(cell.strip() for cell in row)]
    if not rows:
        raise InputError(path, "empty file")
    header = rows[0]
    missing = [name for name in CSV_COLUMNS if name not in header]
    if missing:
        raise InputError(path, f"missing column(s) {missing}; found {header}")
    columns = [header.index(name) for name in CSV_COLUMNS]
    values = np.empty((len(rows) - 1, 2))
    for number, row in enumerate(rows[1:], start=2):
        try:
            values[number - 2] = [float(row[k]) for k in columns]
        except (ValueError, IndexError):
            raise InputError(path, f"row {number}: not two numbers in {row}") from None
    return make_trial(values[:, 0], values[:, 1], source=str(path), label=path.stem)


def write_csv_trial(trial: Trial, path: str | Path) -> None:
    """Write ``trial`` as CSV with header ``time,position``, full float precision, atomically."""
    lines = ["time,position"]
    lines += [
        f"{t!r},{x!r}" for t, x in zip(trial.times.tolist(), trial.positions.tolist(), strict=True)
    ]
    write_atomic_text(path, "\n".join(lines) + "\n")


def read_parquet_trial(path: str | Path) -> Trial:
    """Read a Parquet trial with columns ``time`` and ``position``; metadata from the schema.

    Raises
    ------
    InputError
        Not a Parquet file, a missing column (naming those found), or any `make_trial` problem.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    if not path.is_file():
        raise InputError(path, "no such file")
    try:
        table = pq.read_table(path)
    except (pa.ArrowException, OSError) as error:
        raise InputError(path, f"not a readable Parquet file ({type(error).__name__})") from None
    missing = [name for name in CSV_COLUMNS if name not in table.column_names]
    if missing:
        raise InputError(path, f"missing column(s) {missing}; found {table.column_names}")
    try:
        times, positions = (table.column(n).to_numpy().astype(np.float64) for n in CSV_COLUMNS)
    except (ValueError, TypeError, pa.ArrowException):
        raise InputError(path, "columns time and position must be numeric") from None
    stored = (table.schema.metadata or {}).get(b"mirror_avatar", b"{}")
    try:
        info = json.loads(stored)
    except ValueError:
        raise InputError(path, "schema metadata 'mirror_avatar' is not JSON") from None
    return make_trial(
        times,
        positions,
        source=str(path),
        label=str(info.get("label") or path.stem),
        group=str(info.get("group", "")),
        metadata=dict(info.get("metadata", {})),
    )


def write_parquet_trial(trial: Trial, path: str | Path) -> None:
    """Write ``trial`` as Parquet, keeping label, group and metadata as JSON schema metadata."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    info = {"label": trial.label, "group": trial.group, "metadata": trial.metadata}
    table = pa.table({"time": trial.times, "position": trial.positions})
    table = table.replace_schema_metadata({"mirror_avatar": json.dumps(info)})
    with atomic_path(path) as temporary:
        pq.write_table(table, temporary)


def read_bids_motion(path: str | Path) -> Trial:
    """Read a BIDS-Motion ``*_motion.tsv`` (no header, one position channel) and its sidecar.

    Sample times are ``k / SamplingFrequency`` from the ``*_motion.json`` sidecar.

    Raises
    ------
    InputError
        Sidecar missing, not JSON or without a positive ``SamplingFrequency`` (Hz); a
        non-numeric value (naming the row); or any `make_trial` problem.
    """
    path = Path(path)
    text = _read_text(path)
    sidecar = path.with_name(path.name[: -len(".tsv")] + ".json")
    if not sidecar.is_file():
        raise InputError(path, f"no sidecar {sidecar.name}")
    try:
        info = json.loads(sidecar.read_text(encoding="utf-8"))
        rate = float(info["SamplingFrequency"])
    except (ValueError, KeyError, TypeError):
        raise InputError(path, f"{sidecar.name} has no numeric SamplingFrequency") from None
    if not rate > 0:
        raise InputError(path, f"{sidecar.name}: SamplingFrequency must be positive")
    lines = [line for line in text.splitlines() if line.strip()]
    positions = np.empty(len(lines))
    for number, line in enumerate(lines, start=1):
        try:
            positions[number - 1] = float(line.split("\t")[0])
        except ValueError:
            raise InputError(path, f"row {number}: not a number: {line!r}") from None
    times = np.arange(positions.size) / rate
    label = str(info.get("TaskName") or path.stem)
    return make_trial(times, positions, source=str(path), label=label)


def write_bids_motion(trial: Trial, path: str | Path) -> None:
    """Write a uniformly sampled ``trial`` as BIDS-Motion ``*_motion.tsv`` + ``*_motion.json``."""
    path = Path(path)
    if not path.name.endswith("_motion.tsv"):
        raise InputError(path, "BIDS-Motion file names end in _motion.tsv")
    steps = np.diff(trial.times)
    if not np.allclose(steps, steps[0], rtol=1e-9, atol=0):
        raise InputError(path, "BIDS-Motion needs uniform sampling; resample the trial first")
    sidecar = {
        "TaskName": trial.label or "mirror",
        "SamplingFrequency": 1.0 / float(steps.mean()),
        "MotionChannelCount": 1,
    }
    write_atomic_text(path, "".join(f"{x!r}\n" for x in trial.positions.tolist()))
    json_path = path.with_name(path.name[: -len(".tsv")] + ".json")
    write_atomic_json(json_path, sidecar)


def read_trial(path: str | Path) -> Trial:
    """Read one trial by extension; a ``.mat`` file must hold exactly one trial."""
    trials = _read_file(Path(path))
    if len(trials) != 1:
        raise InputError(path, f"holds {len(trials)} trials, expected one")
    return trials[0]


def _read_file(path: Path) -> list[Trial]:
    suffix = "_motion.tsv" if path.name.endswith("_motion.tsv") else path.suffix.lower()
    if suffix not in SUPPORTED:
        raise InputError(path, f"unknown extension {suffix!r}; supported: {', '.join(SUPPORTED)}")
    if not path.is_file():
        raise InputError(path, "no such file")
    if suffix == ".csv":
        return [read_csv_trial(path)]
    if suffix == ".parquet":
        return [read_parquet_trial(path)]
    if suffix == "_motion.tsv":
        return [read_bids_motion(path)]
    return read_mat_struct(path, MAT_DURATION)


def read_trials(paths: Iterable[str | Path]) -> list[Trial]:
    """Read trial files and directories of them (sorted; group = directory name if unset)."""
    trials: list[Trial] = []
    for path in map(Path, paths):
        if not path.is_dir():
            trials += _read_file(path)
            continue
        files = sorted(p for p in path.iterdir() if p.name.lower().endswith(SUPPORTED))
        if not files:
            raise InputError(path, f"directory holds no trial files ({', '.join(SUPPORTED)})")
        for file in files:
            trials += [t if t.group else replace(t, group=path.name) for t in _read_file(file)]
    return trials


def write_trial(trial: Trial, path: str | Path) -> None:
    """Write one trial by extension (``.csv``, ``.parquet`` or ``_motion.tsv``)."""
    suffix = Path(path).suffix.lower()
    if Path(path).name.endswith("_motion.tsv"):
        write_bids_motion(trial, path)
    elif suffix == ".parquet":
        write_parquet_trial(trial, path)
    elif suffix == ".csv":
        write_csv_trial(trial, path)
    else:
        raise InputError(path, "can only write .csv, .parquet or _motion.tsv")
