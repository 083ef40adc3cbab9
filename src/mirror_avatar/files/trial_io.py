"""Reading and writing trial files, and the checked reading every trial reader shares.

Formats: CSV with header ``time,position`` (the exchange format; extra columns are ignored),
Parquet, and the MATLAB struct format of the bundled data (a 1xK struct array with fields ``x``
and ``v``); BIDS-Motion is read by `mirror_avatar.files.bids.reading` with the checks of this
module,
and `mirror_avatar.files.trial_files` reads and writes any of them by name. Other columns and units
are read as `mirror_avatar.files.importing.ImportOptions` say, several players' columns of one file
as one trial each (``options.columns``). Readers resample only when asked
(``options.resample``); otherwise irregular timestamps are kept (call ``trial.resampled``).
Every reader validates its input and raises
`InputError` with one line naming the file and the problem, whatever the file holds (binary
junk, text that is not UTF-8, damaged or crafted contents, wrong types in JSON); values quoted
from the file are cut to a few dozen characters (`mirror_avatar.files.importing.excerpt`). Files
are opened by `mirror_avatar.files.user_files.open_regular` (regular files only: a named pipe or a
device is refused unopened) and JSON is parsed by `mirror_avatar.files.user_files.parse_json`
(nesting bounded, finite numbers only).

Limits, each refused in one line before the file is parsed further:

- `MAX_FILE_BYTES` (1 GiB): the size of a trial file, and what a MATLAB file's compressed
  variables inflate to;
- `MAX_SAMPLES` (67 108 864, what 1 GiB holds as two float64 columns): the rows of a CSV, TSV
  or Parquet file;
- `MAX_SIDECAR_BYTES` (16 MiB): a ``_motion.json``, a ``_channels.tsv``, a ``--group-by`` map
  and a Parquet file's schema metadata;
- `MAX_NAME_CHARS` (100): a label or group a file names for its trial;
- `MAX_MAT_TRIALS` (1000): the trials (struct elements) of a MATLAB file, counted from the
  struct array's header before anything else of it is read (one when one trial is asked for).

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

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import atomic_path, write_atomic_text
from mirror_avatar.files.importing import (
    COLUMNS_EXAMPLE,
    DEFAULT_IMPORT,
    MISSING_CELLS,
    ImportOptions,
    check_steps,
    excerpt,
    fill_gaps,
    parse_cells,
    read_clock_offsets,
)
from mirror_avatar.files.mat_check import TooManyElements, mat_problem
from mirror_avatar.files.row_widths import ragged_line
from mirror_avatar.files.trials import Trial, make_trial
from mirror_avatar.files.user_files import (
    check_regular,
    open_regular,
    parse_json,
    read_text,
    size_limit,
)

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

MAX_MAT_TRIALS = 1000
"""Most trials (struct elements) read from one MATLAB file (**choice**: each of the bundled files
holds 9). Every trial is spread over `MAT_DURATION` and commands resample it: at 100 Hz the
trials of a file then take at most 1000 x 6001 samples, 48 MB per float64 array, whatever the
file's size (a few bytes of a compressed file can be a trial)."""

PARSE_CHUNK_ROWS = 2**18
"""Rows of text parsed at a time when a file's cells are read one by one to name a bad row."""

MISSING_SPELLINGS = (*MISSING_CELLS, *(cell.upper() for cell in MISSING_CELLS), "NaN")
"""Missing-cell spellings the fast parser knows; others (``Nan``, ``NA `` with a trailing
space) are read by `mirror_avatar.files.importing.parse_cells`."""

Array = NDArray[np.float64]


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
    return read_text(path, MAX_SIDECAR_BYTES)


def check_version(info: dict[str, Any], known: int, source: Path, within: str = "") -> None:
    """Refuse a file whose format ``version`` (``info``'s key) is newer than ``known``.

    A reader reads its format's versions up to the one it writes; a newer file may mean what
    this reader cannot tell, so it is refused rather than read as if it were known. A file
    without the key is of the first version. ``within`` names the object holding ``info`` in
    the file (``MirrorGame``), for the error.

    Raises
    ------
    InputError
        A version that is not a whole number, or is newer than ``known`` (naming ``source``).
    """
    version = info.get("version", 1)
    key = f"{within}.version" if within else "version"
    if isinstance(version, bool) or not isinstance(version, int):
        raise InputError(source, f"{key} {excerpt(version)} is not a whole number")
    if version > known:
        raise InputError(
            source,
            f"{key} {version}: written in a newer format than this mirror-avatar reads (version "
            f"{known} at most); read it with a newer mirror-avatar",
        )


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
            source, f"{what} is {len(text):,} bytes, over the limit {size_limit(MAX_SIDECAR_BYTES)}"
        )
    value = parse_json(text, source, what)
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
    with _reading(path, "CSV" if sep == "," else "TSV"), open_regular(path, MAX_FILE_BYTES) as file:
        frame = pd.read_csv(file, sep=sep, header=None, nrows=1, dtype=str, na_filter=False,
                            encoding="utf-8-sig", skipinitialspace=True)  # fmt: skip
    return [str(cell).strip() for cell in frame.iloc[0]]


def _first_width(path: Path, sep: str) -> int:
    """Return the number of cells of a CSV or TSV file's first non-blank row (`_first_row`).

    A first line of UTF-8 text without double quotes or lone carriage returns is counted by its
    separators; any other is read by `_first_row`.
    """
    with open_regular(path, MAX_FILE_BYTES) as file:
        line = file.readline()
    try:
        body = line.decode("utf-8-sig").rstrip("\r\n")
    except UnicodeDecodeError:
        body = ""
    if body.strip() and '"' not in body and "\r" not in body:
        return body.count(sep) + 1
    return len(_first_row(path, sep))


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
        Not UTF-8, not parseable, more than `MAX_SAMPLES` rows, a line holding more values
        than the first row or, after a header, too few for the columns read (without one:
        fewer than the first row; `refuse_ragged`; a last line without its line end may hold
        fewer, its missing cells then missing), or a cell that is neither a number nor
        missing (naming its row and column).
    """
    refuse_ragged(path, sep, None if first_row == 1 else max(columns) + 1)
    usecols = sorted(set(columns))
    common: dict[str, Any] = {
        "sep": sep, "header": 0 if first_row == 2 else None, "usecols": usecols,
        "encoding": "utf-8-sig", "skipinitialspace": True, "nrows": MAX_SAMPLES + 1,
    }  # fmt: skip
    with _reading(path, "CSV" if sep == "," else "TSV"):
        try:
            with open_regular(path, MAX_FILE_BYTES) as file:
                frame = pd.read_csv(file, dtype=np.float64, keep_default_na=False,
                                    na_values=list(MISSING_SPELLINGS), **common)  # fmt: skip
            values = [frame.iloc[:, k].to_numpy(np.float64) for k in range(len(usecols))]
        except (UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError):
            raise
        except ValueError:
            names = [labels[columns.index(column)] for column in usecols]
            with open_regular(path, MAX_FILE_BYTES) as file:
                chunks = pd.read_csv(file, dtype=str, na_filter=False,
                                     chunksize=PARSE_CHUNK_ROWS, **common)  # fmt: skip
                with chunks:
                    values = _parse_chunks(path, chunks, names, first_row)
    if values[0].size > MAX_SAMPLES:
        raise InputError(path, f"more than {MAX_SAMPLES:,} rows, the limit for trial files")
    return [values[usecols.index(column)] for column in columns]


def refuse_ragged(path: Path, sep: str, fewest: int | None = None) -> None:
    """Refuse a CSV or TSV file with a line of too many or too few values.

    Too many: more than the first row holds; too few: fewer than ``fewest`` (the first row's
    number when None). `mirror_avatar.files.row_widths.ragged_line` finds the line.
    """
    width = _first_width(path, sep)
    with _reading(path, "CSV" if sep == "," else "TSV"):
        found = ragged_line(path, sep, width, MAX_FILE_BYTES, fewest)
    if found is None:
        return
    line, cells = found
    needed = (
        f"the first row holds {width}"
        if cells > width or fewest is None
        else (f"the columns read need {fewest}")
    )
    raise InputError(
        path,
        f"line {line} holds {cells} value{'s' * (cells != 1)} where {needed}: every row needs "
        "one value per column (n/a or an empty cell for a missing one)",
    )


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
    path: str | Path,
    duration: float,
    variable: str | None = None,
    group: str = "",
    max_trials: int = MAX_MAT_TRIALS,
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
    max_trials
        Most trials the file may hold (each struct or cell array's element count, read from its
        header before the array is read).

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
    check_regular(path, MAX_FILE_BYTES)
    with open_regular(path, MAX_FILE_BYTES) as file:
        with _reading(path, "MATLAB"):
            try:
                problem = mat_problem(file, MAX_FILE_BYTES, max_trials)
            except TooManyElements as many:
                raise InputError(path, _too_many_trials(many.count, max_trials)) from None
        if problem:
            raise InputError(path, f"not a readable MATLAB file ({problem})")
        try:
            file.seek(0)
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                contents = scipy.io.loadmat(file)
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


def _too_many_trials(count: int, max_trials: int) -> str:
    """Say that a MATLAB file holds ``count`` trials, more than ``max_trials``."""
    if max_trials == 1:
        return f"holds {count:,} trials, expected one"
    return (
        f"holds {count:,} trials (struct elements), more than the {max_trials:,} read from one "
        "MATLAB file: split it into several files"
    )


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


def only_trial(trials: list[Trial], path: str | Path) -> Trial:
    """Return the one trial of a file, or refuse its several (naming players, if any)."""
    if len(trials) == 1:
        return trials[0]
    players = [str(trial.metadata.get("player", "")) for trial in trials]
    if all(players):
        raise InputError(
            path,
            f"holds {len(trials)} players' trials ({', '.join(players)}), expected one: name "
            "one player in --columns",
        )
    raise InputError(path, f"holds {len(trials)} trials, expected one")


def read_csv_trial(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> Trial:
    """Read a CSV trial of one player (see `read_csv_trials`)."""
    return only_trial(read_csv_trials(path, options), path)


def read_csv_trials(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> list[Trial]:
    """Read a CSV file's trials: by default one, columns ``time,position`` (s, normalised units).

    Other columns and units are read as ``options`` say (an epoch clock's stamps exactly, as
    text: `mirror_avatar.files.importing.clock_offsets`); with ``options.columns`` one trial per
    player. Blank cells are missing samples (`mirror_avatar.files.importing.fill_gaps`). A
    byte-order
    mark is ignored, and so are blank rows. Rows are numbered in error lines as a spreadsheet
    would, without the blank ones.

    Raises
    ------
    InputError
        Empty file, not UTF-8, over `MAX_FILE_BYTES` or `MAX_SAMPLES`, missing column (naming
        the columns found and the options to choose others), a non-numeric value (naming the
        row), or any `import_trial` problem.
    """
    path = Path(path)
    check_regular(path, MAX_FILE_BYTES)
    header = _first_row(path, ",")
    mapping = options.player_columns
    names = (mapping.time, *mapping.columns)
    _check_columns(path, names, header)
    values = _read_numbers(path, [header.index(name) for name in names], names, ",", 2)
    times = values[0]
    if options.time_unit.startswith("epoch"):
        times = read_clock_offsets(path, header.index(mapping.time))
    return [
        import_trial(times, positions, path, options, None, first_row=2, player=label)
        for (label, _), positions in zip(mapping.players, values[1:], strict=True)
    ]


def _check_columns(path: Path, names: Sequence[str], found: Sequence[str]) -> None:
    """Refuse a file without the columns ``names``, naming those ``found`` and the options."""
    missing = [name for name in dict.fromkeys(names) if name not in found]
    if missing:
        raise InputError(
            path,
            f"missing column(s) {_listing(missing)}; found {_listing(found)}: name the columns "
            f"to read with --time-column and --position-column, or several players' with "
            f"--columns (for instance {COLUMNS_EXAMPLE})",
        )


def import_trial(
    times: Array,
    positions: Array,
    path: Path,
    options: ImportOptions,
    position_unit: str | None,
    first_row: int = 1,
    player: str = "",
) -> Trial:
    """Convert a file's columns with ``options``, fill short drop-outs, and validate the trial.

    ``position_unit`` (a unit the file itself names) overrides ``options.position_unit``.
    Rows with neither a time nor a position (NaN in both) are skipped; ``first_row`` is the
    number of the first row in error lines. With ``options.resample`` the trial is
    interpolated onto a uniform grid (`mirror_avatar.files.trials.resample`, PCHIP) after its steps
    are checked against ``options.max_gap`` (`mirror_avatar.files.importing.check_steps`). The
    trial's metadata records the options, how many samples were interpolated and, if
    resampled, the recording's mean rate (``resampled_from``, Hz); ``player`` (a label from
    ``options.columns``) is kept as ``metadata["player"]`` and ends the trial's label.

    Raises
    ------
    InputError
        A row with a position and no finite time, a gap too long to fill or resample over, or
        any `make_trial` problem.
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
    metadata: dict[str, Any] = {"import": options.describe() | {"interpolated_samples": filled}}
    if position_unit is not None:
        metadata["import"]["position_unit"] = position_unit
    source = f"{path} ({player})" if player else str(path)
    if player:
        metadata["player"] = player
    label = f"{path.stem}-{player}" if player else path.stem
    metadata["source"] = str(path)
    trial = make_trial(seconds, normalised, source=source, label=label, metadata=metadata)
    if options.resample is None:
        return trial
    check_steps(trial.times, options.max_gap, source)
    return trial.resampled(options.resample)


def write_csv_trial(trial: Trial, path: str | Path) -> None:
    """Write ``trial`` as CSV with header ``time,position``, full float precision, atomically."""
    lines = ["time,position"]
    lines += [
        f"{t!r},{x!r}" for t, x in zip(trial.times.tolist(), trial.positions.tolist(), strict=True)
    ]
    write_atomic_text(path, "\n".join(lines) + "\n")


def read_parquet_trial(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> Trial:
    """Read a Parquet trial of one player (see `read_parquet_trials`)."""
    return only_trial(read_parquet_trials(path, options), path)


def read_parquet_trials(path: str | Path, options: ImportOptions = DEFAULT_IMPORT) -> list[Trial]:
    """Read a Parquet file's trials, by default one of columns ``time`` and ``position``.

    Other columns and units are read as ``options`` say (see `read_csv_trials`); the columns
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
    check_regular(path, MAX_FILE_BYTES)
    mapping = options.player_columns
    names = (mapping.time, *mapping.columns)
    try:
        with open_regular(path, MAX_FILE_BYTES) as file, pq.ParquetFile(file) as parquet:
            schema = parquet.schema_arrow
            _check_columns(path, names, schema.names)
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
            values = [
                table.column(name).cast(pa.float64(), safe=False).to_numpy() for name in names
            ]
            del table
    except (pa.ArrowException, OSError, UnicodeDecodeError) as error:
        raise InputError(path, f"not a readable Parquet file ({type(error).__name__})") from None
    stored = (schema.metadata or {}).get(b"mirror_avatar")
    where = "schema metadata 'mirror_avatar'"
    info = {} if stored is None else _json_object(stored, path, where)
    extra = info.get("metadata", {})
    if not isinstance(extra, dict):
        raise InputError(path, f"{where}: metadata is {_json_kind(extra)}, not an object")
    label = _name_in(info, "label", path, f"{where}: ") or path.stem
    group = _name_in(info, "group", path, f"{where}: ")
    trials = []
    for (player, _), positions in zip(mapping.players, values[1:], strict=True):
        trial = import_trial(values[0], positions, path, options, None, player=player)
        trials.append(
            replace(
                trial,
                label=f"{label}-{player}" if player else label,
                group=group,
                metadata=extra | trial.metadata,
            )
        )
    return trials


def write_parquet_trial(trial: Trial, path: str | Path) -> None:
    """Write ``trial`` as Parquet, keeping label, group and metadata as JSON schema metadata."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    info = {"label": trial.label, "group": trial.group, "metadata": trial.metadata}
    table = pa.table({"time": trial.times, "position": trial.positions})
    table = table.replace_schema_metadata({"mirror_avatar": json.dumps(info)})
    with atomic_path(path) as temporary:
        pq.write_table(table, temporary)
