"""Reading and writing trial files.

Formats: CSV with header ``time,position`` (the exchange format; extra columns are ignored),
Parquet, BIDS-Motion (``*_motion.tsv`` with its ``_motion.json`` and, if present,
``_channels.tsv``), and the MATLAB struct format of the bundled data (a 1xK struct array with
fields ``x`` and ``v``). Other columns and units are read as `mirror_avatar.importing.ImportOptions`
say. Readers do not resample: irregular timestamps are kept (call ``trial.resampled``). Every
reader validates its input and raises `InputError` with one line naming the file and the problem.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import scipy.io
from numpy.typing import NDArray

from mirror_avatar.atomic import atomic_path, write_atomic_json, write_atomic_text
from mirror_avatar.errors import InputError
from mirror_avatar.importing import (
    DEFAULT_IMPORT,
    POSITION_UNITS,
    ImportOptions,
    fill_gaps,
    parse_number,
)
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


def read_csv_trial(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> Trial:
    """Read a CSV trial: by default columns ``time,position`` (s, normalised units).

    Other columns and units are read as ``options`` say; blank cells are missing samples
    (`mirror_avatar.importing.fill_gaps`). A byte-order mark is ignored.

    Raises
    ------
    InputError
        Empty file, missing column (naming the columns found and the options to choose
        others), a non-numeric value (naming the row), or any problem `make_trial` finds.
    """
    path = Path(path)
    rows = list(csv.reader(io.StringIO(_read_text(path).removeprefix("\ufeff"))))
    rows = [[cell.strip() for cell in row] for row in rows if any(cell.strip() for cell in row)]
    if not rows:
        raise InputError(path, "empty file")
    header = rows[0]
    names = (options.time_column, options.position_column)
    missing = [name for name in names if name not in header]
    if missing:
        raise InputError(
            path,
            f"missing column(s) {missing}; found {header[:8]}: name the columns to read with "
            "--time-column and --position-column",
        )
    columns = [header.index(name) for name in names]
    values = np.empty((len(rows) - 1, 2))
    for number, row in enumerate(rows[1:], start=2):
        try:
            values[number - 2] = [parse_number(row[k]) if k < len(row) else np.nan for k in columns]
        except ValueError:
            shown = [row[k][:20] for k in columns if k < len(row)]
            raise InputError(path, f"row {number}: not numbers in {shown}") from None
    if np.isnan(values[:, 0]).any():
        first = int(np.argmax(np.isnan(values[:, 0]))) + 2
        raise InputError(path, f"row {first}: no time in column {options.time_column!r}")
    return import_trial(values[:, 0], values[:, 1], path, options, None)


def import_trial(
    times: NDArray[np.float64],
    positions: NDArray[np.float64],
    path: Path,
    options: ImportOptions,
    position_unit: str | None,
) -> Trial:
    """Convert a file's columns with ``options``, fill short drop-outs, and validate the trial.

    ``position_unit`` (a unit the file itself names) overrides ``options.position_unit``.
    The trial's metadata records the options and how many samples were interpolated.
    """
    seconds = options.seconds(times, str(path))
    normalised = options.normalised(positions, position_unit)
    seconds, normalised, filled = fill_gaps(seconds, normalised, options.max_gap, str(path))
    metadata = {"import": options.describe() | {"interpolated_samples": filled}}
    if position_unit is not None:
        metadata["import"]["position_unit"] = position_unit
    return make_trial(seconds, normalised, source=str(path), label=path.stem, metadata=metadata)


def write_csv_trial(trial: Trial, path: str | Path) -> None:
    """Write ``trial`` as CSV with header ``time,position``, full float precision, atomically."""
    lines = ["time,position"]
    lines += [
        f"{t!r},{x!r}" for t, x in zip(trial.times.tolist(), trial.positions.tolist(), strict=True)
    ]
    write_atomic_text(path, "\n".join(lines) + "\n")


def read_parquet_trial(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> Trial:
    """Read a Parquet trial, by default columns ``time`` and ``position``; metadata from the schema.

    Other columns and units are read as ``options`` say (see `read_csv_trial`).

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
    names = (options.time_column, options.position_column)
    missing = [name for name in names if name not in table.column_names]
    if missing:
        raise InputError(
            path,
            f"missing column(s) {missing}; found {table.column_names[:8]}: name the columns to "
            "read with --time-column and --position-column",
        )
    try:
        times, positions = (
            table.column(n).to_numpy(zero_copy_only=False).astype(np.float64) for n in names
        )
    except (ValueError, TypeError, pa.ArrowException):
        raise InputError(path, f"columns {list(names)} must be numeric") from None
    stored = (table.schema.metadata or {}).get(b"mirror_avatar", b"{}")
    try:
        info = json.loads(stored)
    except ValueError:
        raise InputError(path, "schema metadata 'mirror_avatar' is not JSON") from None
    if not isinstance(info, dict):
        raise InputError(path, "schema metadata 'mirror_avatar' is not a JSON object")
    trial = import_trial(times, positions, path, options, None)
    return replace(
        trial,
        label=str(info.get("label") or path.stem),
        group=str(info.get("group", "")),
        metadata=dict(info.get("metadata", {})) | trial.metadata,
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


def read_bids_motion(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> Trial:
    """Read a BIDS-Motion ``*_motion.tsv`` (no header) with its ``_motion.json`` sidecar.

    Sample times are ``k / SamplingFrequency`` from the sidecar. With a ``*_channels.tsv`` beside
    it, the position channel is the one ``options.position_column`` names, or the only one of
    type ``POS``, and its ``units`` (mm, cm, m) convert it; without one, the file must hold one
    column. Blank or ``n/a`` samples are missing (`mirror_avatar.importing.fill_gaps`).

    Raises
    ------
    InputError
        Sidecar missing, not JSON or without a positive ``SamplingFrequency`` (Hz); several
        channels and none chosen (naming them and ``--position-column``); a non-numeric value
        (naming the row); or any `make_trial` problem.
    """
    path = Path(path)
    text = _read_text(path)
    stem = path.name[: -len("_motion.tsv")]
    sidecar = path.with_name(f"{stem}_motion.json")
    if not sidecar.is_file():
        raise InputError(path, f"no sidecar {sidecar.name}")
    try:
        info = json.loads(sidecar.read_text(encoding="utf-8"))
        rate = float(info["SamplingFrequency"])
    except (ValueError, KeyError, TypeError, OverflowError):
        raise InputError(path, f"{sidecar.name} has no numeric SamplingFrequency") from None
    if not (np.isfinite(rate) and rate > 0):
        raise InputError(path, f"{sidecar.name}: SamplingFrequency must be positive")
    lines = [line.split("\t") for line in text.splitlines() if line.strip()]
    column, unit = _bids_channel(path, path.with_name(f"{stem}_channels.tsv"), options, lines)
    positions = np.empty(len(lines))
    for number, line in enumerate(lines, start=1):
        try:
            positions[number - 1] = parse_number(line[column]) if column < len(line) else np.nan
        except ValueError:
            raise InputError(path, f"row {number}: not a number: {line[column][:20]!r}") from None
    times = np.arange(positions.size) / rate
    trial = import_trial(times, positions, path, replace(options, time_unit="s"), unit)
    return replace(trial, label=str(info.get("TaskName") or path.stem))


def _bids_channel(
    path: Path, channels: Path, options: ImportOptions, lines: list[list[str]]
) -> tuple[int, str | None]:
    """Return the position channel's column and unit (None: as the options say)."""
    if not channels.is_file():
        if lines and len(lines[0]) > 1:
            raise InputError(
                path,
                f"{len(lines[0])} columns and no {channels.name} naming them: give the channels "
                "file, or keep one column",
            )
        return 0, None
    table = list(csv.DictReader(io.StringIO(_read_text(channels)), delimiter="\t"))
    names = [row.get("name", "") for row in table]
    if options.position_column in names:
        index = names.index(options.position_column)
    else:
        positional = [i for i, row in enumerate(table) if row.get("type", "").upper() == "POS"]
        if len(table) == 1:
            positional = [0]
        if len(positional) != 1:
            raise InputError(
                path,
                f"{len(table)} channels ({', '.join(names[:8])}): choose the position channel "
                "with --position-column NAME",
            )
        index = positional[0]
    unit = table[index].get("units", "").strip()
    if unit in ("", "n/a"):
        return index, None
    if unit not in POSITION_UNITS:
        raise InputError(
            channels, f"unit {unit[:20]!r} of channel {names[index]!r} is not mm, cm or m"
        )
    return index, unit


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


def read_trial(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> Trial:
    """Read one trial by extension; a ``.mat`` file must hold exactly one trial."""
    trials = read_trial_file(path, options)
    if len(trials) != 1:
        raise InputError(path, f"holds {len(trials)} trials, expected one")
    return trials[0]


def read_trial_file(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> list[Trial]:
    """Read the trials of one file by its extension (a ``.mat`` file may hold several).

    Folders of files are read by `mirror_avatar.trial_sets.read_trial_set`.
    """
    path = Path(path)
    suffix = "_motion.tsv" if path.name.endswith("_motion.tsv") else path.suffix.lower()
    if suffix not in SUPPORTED:
        raise InputError(
            path,
            f"unknown extension {suffix!r}; trial files are {', '.join(SUPPORTED)}"
            + (" (a folder name? it does not exist)" if not suffix else ""),
        )
    if not path.is_file():
        raise InputError(path, "no such file")
    if suffix == ".csv":
        return [read_csv_trial(path, options)]
    if suffix == ".parquet":
        return [read_parquet_trial(path, options)]
    if suffix == "_motion.tsv":
        return [read_bids_motion(path, options)]
    return read_mat_struct(path, MAT_DURATION)


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
