"""Reading and writing trial files.

Formats: CSV with header ``time,position`` (the exchange format; extra columns are ignored),
Parquet, BIDS-Motion (``*_motion.tsv`` with its ``_motion.json`` and, if present,
``_channels.tsv``), and the MATLAB struct format of the bundled data (a 1xK struct array with
fields ``x`` and ``v``). Other columns and units are read as `mirror_avatar.importing.ImportOptions`
say. Readers do not resample: irregular timestamps are kept (call ``trial.resampled``). Every
reader validates its input and raises `InputError` with one line naming the file and the problem,
whatever the file holds (binary junk, text that is not UTF-8, damaged or crafted contents, wrong
types in JSON); values quoted from the file are cut to a few dozen characters
(`mirror_avatar.importing.excerpt`).

Limits, each refused in one line before the file is parsed further:

- `MAX_FILE_BYTES` (1 GiB): the size of a trial file, and what a MATLAB file's compressed
  variables inflate to;
- `MAX_SAMPLES` (67 108 864, what 1 GiB holds as two float64 columns): the rows of a CSV, TSV
  or Parquet file;
- `MAX_SIDECAR_BYTES` (16 MiB): a ``_motion.json``, a ``_channels.tsv``, a ``--group-by`` map
  and a Parquet file's schema metadata;
- `MAX_NAME_CHARS` (100): a label or group a file names for its trial.

Memory: the numeric columns are parsed straight into float64 arrays (pandas' C parser for CSV
and TSV, Arrow for Parquet; only the two columns needed), so reading a text file peaks at a small
multiple of its size (``benchmarks/bench_reading.py`` measures the multiple). Compressed formats
can hold far more than their size on disk: a Parquet file is bounded by `MAX_SAMPLES` rows, a
MATLAB file by what its variables inflate to (`MAX_FILE_BYTES`), both checked from the file's own
metadata before its data are read. A text file with
cells that the fast parser refuses (a value that is not a number, a missing-value spelling it
does not know) is parsed again in chunks of `PARSE_CHUNK_ROWS` rows to name the row.
"""

from __future__ import annotations

import json
import stat
import warnings
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import scipy.io
from numpy.typing import NDArray

from mirror_avatar.atomic import atomic_path, write_atomic_json, write_atomic_text
from mirror_avatar.errors import InputError
from mirror_avatar.importing import (
    DEFAULT_IMPORT,
    MISSING_CELLS,
    POSITION_UNITS,
    ImportOptions,
    excerpt,
    fill_gaps,
    parse_cells,
    read_clock_offsets,
)
from mirror_avatar.mat_check import mat_problem
from mirror_avatar.trials import MAX_RATE, MIN_RATE, Trial, make_trial

MAX_FILE_BYTES = 2**30
"""Largest trial file read, and the most a MATLAB file's compressed variables may inflate to
(bytes; 1 GiB, **choice**). Larger files are refused so that reading stays within a small
multiple of this in memory."""

MAX_SAMPLES = MAX_FILE_BYTES // 16
"""Most rows read from a CSV, TSV or Parquet file: `MAX_FILE_BYTES` of two float64 columns."""

MAX_SIDECAR_BYTES = 2**24
"""Largest JSON sidecar, ``_channels.tsv``, ``--group-by`` map or Parquet schema metadata read
(bytes; 16 MiB, **choice**)."""

MAX_NAME_CHARS = 100
"""Longest label or group a file may name for its trial (Parquet schema metadata, BIDS
``TaskName``; **choice**): they become file and folder names."""

PARSE_CHUNK_ROWS = 2**18
"""Rows of text parsed at a time when a file's cells are read one by one to name a bad row."""

MISSING_SPELLINGS = (*MISSING_CELLS, *(cell.upper() for cell in MISSING_CELLS), "NaN")
"""Missing-cell spellings the fast parser knows; others (``Nan``, ``NA `` with a trailing
space) are read by `mirror_avatar.importing.parse_cells`."""

Array = NDArray[np.float64]


def _check_file(path: Path, limit: int = MAX_FILE_BYTES) -> None:
    """Refuse a path that is not a readable regular file of at most ``limit`` bytes."""
    try:
        status = path.stat()
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except OSError as error:
        raise InputError(path, f"cannot be read ({error.strerror})") from None
    if not stat.S_ISREG(status.st_mode):
        raise InputError(path, "not a regular file")
    if status.st_size > limit:
        raise InputError(path, f"{status.st_size:,} bytes, over the limit {_size(limit)}")


def _size(limit: int) -> str:
    """Describe a byte limit for an error line: exact, and in MiB."""
    return f"of {limit:,} bytes ({limit / 2**20:g} MiB) for files read"


@contextmanager
def _reading(path: Path, kind: str) -> Iterator[None]:
    """Turn the errors of reading ``path`` as ``kind`` text into one-line `InputError` s."""
    try:
        yield
    except UnicodeDecodeError:
        raise InputError(path, "not UTF-8 text (save it as UTF-8)") from None
    except pd.errors.EmptyDataError:
        raise InputError(path, "empty file") from None
    except pd.errors.ParserError as error:
        problem = str(error).removeprefix("Error tokenizing data. C error: ")
        raise InputError(path, f"not a valid {kind} file ({problem})") from None
    except OSError as error:
        raise InputError(
            path, f"cannot be read ({error.strerror or type(error).__name__})"
        ) from None


def read_sidecar_text(path: Path) -> str:
    """Read a small UTF-8 text file kept beside trials (at most `MAX_SIDECAR_BYTES`).

    A byte-order mark is dropped.

    Raises
    ------
    InputError
        Missing, too large, unreadable or not UTF-8.
    """
    _check_file(path, MAX_SIDECAR_BYTES)
    with _reading(path, "text"):
        return path.read_text(encoding="utf-8-sig")


def _listing(values: Sequence[object], count: int = 8) -> str:
    """Show the first ``count`` values, each cut by `excerpt`, as a bracketed list."""
    shown = ", ".join(excerpt(value) for value in values[:count])
    return f"[{shown}{', ...' if len(values) > count else ''}]"


def _json_kind(value: object) -> str:
    """Name a JSON value's type for an error line."""
    kinds = {dict: "an object", list: "a list", str: "text", bool: "true or false",
             int: "a number", float: "a number", type(None): "null"}  # fmt: skip
    return kinds.get(type(value), type(value).__name__)


def _json_object(text: str | bytes, source: Path, what: str) -> dict[str, Any]:
    """Parse ``text`` (``what``, in ``source``) as a JSON object of at most `MAX_SIDECAR_BYTES`."""
    if len(text) > MAX_SIDECAR_BYTES:
        raise InputError(
            source, f"{what} is {len(text):,} bytes, over the limit {_size(MAX_SIDECAR_BYTES)}"
        )
    try:
        value = json.loads(text)
    except json.JSONDecodeError as error:
        raise InputError(
            source, f"{what} is not JSON ({error.msg} at line {error.lineno})"
        ) from None
    except (ValueError, RecursionError):
        raise InputError(
            source,
            f"{what} is not JSON that can be read (not UTF-8, nested too deeply or a number "
            "too long)",
        ) from None
    if not isinstance(value, dict):
        raise InputError(source, f"{what} is {_json_kind(value)}, not a JSON object")
    return value


def _name_in(info: dict[str, Any], key: str, source: Path, what: str) -> str:
    """Return the label or group ``info[key]`` names (``""`` if absent), if a short name."""
    value = info.get(key)
    if value is None:
        return ""
    if not isinstance(value, str):
        raise InputError(source, f"{what}{key} is {_json_kind(value)}, not text")
    if len(value) > MAX_NAME_CHARS or value.strip() in (".", ".."):
        raise InputError(
            source,
            f"{what}{key} {excerpt(value)} is not a usable name (at most {MAX_NAME_CHARS} "
            "characters, not . or ..)",
        )
    return value


def _first_row(path: Path, sep: str) -> list[str]:
    """Return the cells of the first non-blank row of a CSV or TSV file, stripped."""
    with _reading(path, "CSV" if sep == "," else "TSV"):
        frame = pd.read_csv(path, sep=sep, header=None, nrows=1, dtype=str, na_filter=False,
                            encoding="utf-8-sig", skipinitialspace=True)  # fmt: skip
    return [str(cell).strip() for cell in frame.iloc[0]]


def _read_numbers(
    path: Path, columns: Sequence[int], labels: Sequence[str], sep: str, first_row: int
) -> list[Array]:
    """Read columns of a CSV or TSV file as float64 arrays, shape (n,) each, NaN where missing.

    Parameters
    ----------
    path
        The file; with ``first_row`` 2 its first non-blank row is a header and is skipped.
    columns, labels
        Positions of the columns in a row (from 0), and their names for error lines.
    sep
        ``","`` (CSV) or a tab (TSV).
    first_row
        The number of the first data row in error lines (blank lines are not counted).

    Raises
    ------
    InputError
        Not UTF-8, not parseable, more than `MAX_SAMPLES` rows, or a cell that is neither a
        number nor missing (naming its row and column).
    """
    usecols = sorted(set(columns))
    common: dict[str, Any] = {
        "sep": sep, "header": 0 if first_row == 2 else None, "usecols": usecols,
        "encoding": "utf-8-sig", "skipinitialspace": True, "nrows": MAX_SAMPLES + 1,
    }  # fmt: skip
    with _reading(path, "CSV" if sep == "," else "TSV"):
        try:
            frame = pd.read_csv(path, dtype=np.float64, keep_default_na=False,
                                na_values=list(MISSING_SPELLINGS), **common)  # fmt: skip
            values = [frame.iloc[:, k].to_numpy(np.float64) for k in range(len(usecols))]
        except (UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError):
            raise
        except ValueError:
            names = [labels[columns.index(column)] for column in usecols]
            with pd.read_csv(path, dtype=str, na_filter=False, chunksize=PARSE_CHUNK_ROWS,
                             **common) as chunks:  # fmt: skip
                values = _parse_chunks(path, chunks, names, first_row)
    if values[0].size > MAX_SAMPLES:
        raise InputError(path, f"more than {MAX_SAMPLES:,} rows, the limit for trial files")
    return [values[usecols.index(column)] for column in columns]


def _parse_chunks(
    path: Path, chunks: Iterable[pd.DataFrame], labels: Sequence[str], first_row: int
) -> list[Array]:
    """Read text chunks cell by cell (`parse_cells`), naming the first cell that is no number."""
    parts: list[list[Array]] = [[] for _ in labels]
    for chunk in chunks:
        for k, label in enumerate(labels):
            cells = chunk.iloc[:, k]
            numbers, bad = parse_cells(cells)
            if bad is not None:
                raise InputError(
                    path,
                    f"row {int(chunk.index[bad]) + first_row}: {excerpt(cells.iloc[bad])} in "
                    f"column {excerpt(label)} is not a number",
                )
            parts[k].append(numbers)
    return [np.concatenate(part) if part else np.empty(0) for part in parts]


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

    Raises
    ------
    InputError
        Not a MATLAB file, over a size limit (`MAX_FILE_BYTES`, also for what its compressed
        variables inflate to), no struct array with a field ``x``, an empty one, an ``x`` that
        is not a vector of real numbers, or any `make_trial` problem.
    """
    path = Path(path)
    _check_file(path)
    with _reading(path, "MATLAB"):
        problem = mat_problem(path, MAX_FILE_BYTES)
    if problem:
        raise InputError(path, f"not a readable MATLAB file ({problem})")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            contents = scipy.io.loadmat(path)
    except Exception as error:  # scipy raises many types (and warnings) for corrupt files
        raise InputError(path, f"not a readable MATLAB file ({type(error).__name__})") from None
    names = [name for name in contents if not name.startswith("__")]
    if variable is None:
        if len(names) != 1:
            raise InputError(path, f"expected one variable, found {len(names)}: {_listing(names)}")
        variable = names[0]
    if variable not in contents:
        raise InputError(path, f"no variable {excerpt(variable)}; it has {_listing(names)}")
    struct_array = np.asarray(contents[variable])
    if struct_array.dtype.names is None or "x" not in struct_array.dtype.names:
        raise InputError(
            path, f"variable {excerpt(variable)} is not a struct array with a field 'x'"
        )
    if struct_array.size == 0:
        raise InputError(path, f"variable {excerpt(variable)} is an empty struct array")
    trials = []
    for k, element in enumerate(struct_array.ravel()):
        positions = _mat_positions(element["x"], f"{path}[{k}]")
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


MAT_KINDS = {"U": "text", "S": "text", "c": "complex numbers", "b": "logical values",
             "O": "a cell array", "V": "a struct"}  # fmt: skip
"""What a MATLAB field of each NumPy dtype kind holds, for error lines."""


def _mat_positions(value: object, source: str) -> Array:
    """Return a struct element's field ``x`` as positions, shape (n,), if a real vector."""
    array = np.asarray(value)
    if array.dtype.kind not in "iuf":
        kind = MAT_KINDS.get(array.dtype.kind, str(array.dtype))
        raise InputError(source, f"field 'x' holds {kind}, not positions")
    if array.size and array.size != max(array.shape, default=1):
        shape = "x".join(map(str, array.shape))
        raise InputError(source, f"field 'x' is a {shape} array, not a vector of positions")
    return array.astype(np.float64).ravel()


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


def read_csv_trial(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> Trial:
    """Read a CSV trial: by default columns ``time,position`` (s, normalised units).

    Other columns and units are read as ``options`` say (an epoch clock's stamps exactly, as
    text: `mirror_avatar.importing.clock_offsets`); blank cells are missing samples
    (`mirror_avatar.importing.fill_gaps`). A byte-order mark is ignored, and so are blank rows.
    Rows are numbered in error lines as a spreadsheet would, without the blank ones.

    Raises
    ------
    InputError
        Empty file, not UTF-8, over `MAX_FILE_BYTES` or `MAX_SAMPLES`, missing column (naming
        the columns found and the options to choose others), a non-numeric value (naming the
        row), or any `import_trial` problem.
    """
    path = Path(path)
    _check_file(path)
    header = _first_row(path, ",")
    names = (options.time_column, options.position_column)
    missing = [name for name in names if name not in header]
    if missing:
        raise InputError(
            path,
            f"missing column(s) {_listing(missing)}; found {_listing(header)}: name the columns "
            "to read with --time-column and --position-column",
        )
    times, positions = _read_numbers(path, [header.index(name) for name in names], names, ",", 2)
    if options.time_unit.startswith("epoch"):
        times = read_clock_offsets(path, header.index(options.time_column))
    return import_trial(times, positions, path, options, None, first_row=2)


def import_trial(
    times: Array,
    positions: Array,
    path: Path,
    options: ImportOptions,
    position_unit: str | None,
    first_row: int = 1,
) -> Trial:
    """Convert a file's columns with ``options``, fill short drop-outs, and validate the trial.

    ``position_unit`` (a unit the file itself names) overrides ``options.position_unit``.
    Rows with neither a time nor a position (NaN in both) are skipped; ``first_row`` is the
    number of the first row in error lines. The trial's metadata records the options and how
    many samples were interpolated.

    Raises
    ------
    InputError
        A row with a position and no finite time, a gap too long to fill, or any `make_trial`
        problem.
    """
    blank = np.isnan(times) & np.isnan(positions)
    untimed = ~np.isfinite(times) & ~blank
    if untimed.any():
        row = int(np.argmax(untimed))
        value = "missing" if np.isnan(times[row]) else f"{times[row]:g}"
        raise InputError(
            path,
            f"row {row + first_row}: time is {value} in column {excerpt(options.time_column)}",
        )
    if blank.any():
        times, positions = times[~blank], positions[~blank]
    with np.errstate(over="ignore"):
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

    Other columns and units are read as ``options`` say (see `read_csv_trial`); the two columns
    must hold integers or floating-point numbers, nulls being missing samples. Label, group and
    metadata come from the JSON schema metadata ``mirror_avatar`` that `write_parquet_trial`
    writes.

    Raises
    ------
    InputError
        Not a Parquet file, over `MAX_FILE_BYTES` or `MAX_SAMPLES`, a missing column (naming
        those found) or one that does not hold numbers, schema metadata that is not a JSON
        object with a text label and group (at most `MAX_NAME_CHARS`) and an object metadata,
        or any `import_trial` problem.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    _check_file(path)
    names = (options.time_column, options.position_column)
    try:
        with pq.ParquetFile(path) as parquet:
            schema = parquet.schema_arrow
            missing = [name for name in names if name not in schema.names]
            if missing:
                raise InputError(
                    path,
                    f"missing column(s) {_listing(missing)}; found {_listing(schema.names)}: name "
                    "the columns to read with --time-column and --position-column",
                )
            for name in names:
                kind = schema.field(schema.names.index(name)).type
                if not (pa.types.is_integer(kind) or pa.types.is_floating(kind)):
                    raise InputError(path, f"column {excerpt(name)} holds {kind}, not numbers")
            if parquet.metadata.num_rows > MAX_SAMPLES:
                raise InputError(
                    path,
                    f"{parquet.metadata.num_rows:,} rows, over the limit of {MAX_SAMPLES:,} for "
                    "trial files",
                )
            table = parquet.read(columns=list(dict.fromkeys(names)))
            times, positions = (
                table.column(name).cast(pa.float64(), safe=False).to_numpy() for name in names
            )
            del table
    except (pa.ArrowException, OSError, UnicodeDecodeError) as error:
        raise InputError(path, f"not a readable Parquet file ({type(error).__name__})") from None
    stored = (schema.metadata or {}).get(b"mirror_avatar")
    where = "schema metadata 'mirror_avatar'"
    info = {} if stored is None else _json_object(stored, path, where)
    extra = info.get("metadata", {})
    if not isinstance(extra, dict):
        raise InputError(path, f"{where}: metadata is {_json_kind(extra)}, not an object")
    trial = import_trial(times, positions, path, options, None)
    return replace(
        trial,
        label=_name_in(info, "label", path, f"{where}: ") or path.stem,
        group=_name_in(info, "group", path, f"{where}: "),
        metadata=extra | trial.metadata,
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
    column. Blank or ``n/a`` samples are missing (`mirror_avatar.importing.fill_gaps`). The
    label is the sidecar's ``TaskName``.

    Raises
    ------
    InputError
        Sidecar missing, not a JSON object, without a ``SamplingFrequency`` that is a number
        between `mirror_avatar.trials.MIN_RATE` and `mirror_avatar.trials.MAX_RATE` Hz, or with
        a ``TaskName`` that is not a short text; several channels and none chosen (naming them
        and ``--position-column``); a non-numeric value (naming the row); a size limit; or any
        `import_trial` problem.
    """
    path = Path(path)
    _check_file(path)
    stem = path.name[: -len("_motion.tsv")]
    sidecar = path.with_name(f"{stem}_motion.json")
    if not sidecar.is_file():
        raise InputError(path, f"no sidecar {sidecar.name}")
    info = _json_object(read_sidecar_text(sidecar), sidecar, "the sidecar")
    rate = _sampling_frequency(info, sidecar)
    label = _name_in(info, "TaskName", sidecar, "")
    width = len(_first_row(path, "\t"))
    column, name, unit = _bids_channel(path, path.with_name(f"{stem}_channels.tsv"), options, width)
    (positions,) = _read_numbers(path, [column], [name], "\t", 1)
    times = np.arange(positions.size) / rate
    trial = import_trial(times, positions, path, replace(options, time_unit="s"), unit)
    return replace(trial, label=label or path.stem)


def _sampling_frequency(info: dict[str, Any], sidecar: Path) -> float:
    """Return the sidecar's ``SamplingFrequency`` (Hz) if it is a rate a trial can have."""
    if "SamplingFrequency" not in info:
        raise InputError(sidecar, "no SamplingFrequency (Hz)")
    value = info["SamplingFrequency"]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(sidecar, f"SamplingFrequency is {_json_kind(value)}, not a number of Hz")
    if not MIN_RATE <= value <= MAX_RATE:
        raise InputError(
            sidecar,
            f"SamplingFrequency {excerpt(value)} Hz is outside {MIN_RATE:g}-{MAX_RATE:g} Hz",
        )
    return float(value)


def _bids_channel(
    path: Path, channels: Path, options: ImportOptions, width: int
) -> tuple[int, str, str | None]:
    """Return the position channel's column, name and unit (None: as the options say).

    ``width`` is the number of columns in the first row of the motion file ``path``.
    """
    if not channels.is_file():
        if width > 1:
            raise InputError(
                path,
                f"{width} columns and no {channels.name} naming them: give the channels "
                "file, or keep one column",
            )
        return 0, "1", None
    _check_file(channels, MAX_SIDECAR_BYTES)
    with _reading(channels, "TSV"):
        table = pd.read_csv(channels, sep="\t", dtype=str, na_filter=False, encoding="utf-8-sig")
    rows = [{str(key).strip(): str(value).strip() for key, value in row.items()}
            for row in table.to_dict("records")]  # fmt: skip
    names = [row.get("name", "") for row in rows]
    if options.position_column in names:
        index = names.index(options.position_column)
    else:
        positional = [i for i, row in enumerate(rows) if row.get("type", "").upper() == "POS"]
        if len(rows) == 1:
            positional = [0]
        if len(positional) != 1:
            shown = ", ".join(excerpt(name, quote=False) for name in names[:8])
            raise InputError(
                path,
                f"{len(rows)} channels ({shown}): choose the position channel "
                "with --position-column NAME",
            )
        index = positional[0]
    if index >= width:
        raise InputError(
            channels,
            f"channel {excerpt(names[index])} is column {index + 1}, but {path.name} has {width}",
        )
    unit = rows[index].get("units", "")
    if unit in ("", "n/a"):
        return index, names[index], None
    if unit not in POSITION_UNITS:
        raise InputError(
            channels, f"unit {excerpt(unit)} of channel {excerpt(names[index])} is not mm, cm or m"
        )
    return index, names[index], unit


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
