"""File writes that fail cleanly, naming their file.

Atomic writes (`atomic_path` and the functions on it): a failure never leaves a half-written file
or set, or clobbers a good one. Recordings written as they happen (`LineFile`): every line is
flushed as it is written, so a crash keeps every complete line. Either way a failed write (a
full disk, a file-size limit) raises an `OSError` naming the file, also when the system's own
error named none (``[Errno 27] File too large``).

Also the one conversion of results to plain JSON (`json_safe`): numpy scalars and arrays become
numbers and lists, NaN and infinities ``null``; and of tables to CSV a spreadsheet opens as text
(`csv_text`, read back by `csv_cells`).
"""

from __future__ import annotations

import io
import json
import logging
import math
import os
import tempfile
from collections.abc import Iterator, Mapping
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

logger = logging.getLogger(__name__)

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
"""The first characters that make a spreadsheet read a CSV cell as a formula (OWASP)."""

TEXT_MARK = "'"
"""What `csv_text` puts before a text cell a spreadsheet would read as a formula."""


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path in the directory of ``path``; rename it over ``path`` on success.

    Parameters
    ----------
    path
        The file to write.

    Yields
    ------
    Path
        Where to write; removed if the body raises.

    Raises
    ------
    OSError
        The write failed (a full disk, a file-size limit): the error names ``path``, also when
        the system's error named no file.
    """
    path = Path(path)
    handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(handle)
    temporary = Path(name)
    temporary.chmod(_file_mode(path))
    try:
        yield temporary
        os.replace(temporary, path)
    except OSError as error:
        if error.filename is not None and error.filename != str(temporary):
            raise
        raise naming(error, path) from error
    finally:
        temporary.unlink(missing_ok=True)


def naming(error: OSError, path: str | Path) -> OSError:
    """Return ``error`` as an `OSError` of the same number naming ``path``."""
    return OSError(error.errno, error.strerror or str(error), str(path))


class LineFile:
    """A new UTF-8 text file written line by line, each line flushed as it is written.

    Parameters
    ----------
    path
        The file; it must not exist yet.
    header
        Its first line (without the line end).

    Raises
    ------
    OSError
        From the constructor and `write` when the file cannot be written (a full disk, a
        file-size limit), naming ``path``; the complete lines written before stay.
    """

    def __init__(self, path: str | Path, header: str) -> None:
        self.path = Path(path)
        self._file: IO[str] = self.path.open("x", encoding="utf-8", newline="\n")
        try:
            self.write(header)
        except OSError:
            self.close()
            raise

    def write(self, line: str) -> None:
        """Append ``line`` and its line end, flushed to the system at once."""
        try:
            self._file.write(line + "\n")
            self._file.flush()
        except OSError as error:
            raise naming(error, self.path) from error

    def close(self) -> None:
        """Close the file, writing what a failed write left unflushed if it now can.

        If it cannot, a logged warning names the file; the complete lines stay.
        """
        try:
            self._file.close()
        except OSError as error:
            logger.warning("%s: its last line could not be written: %s", self.path, error.strerror)


def _file_mode(path: Path) -> int:
    """Permissions for ``path``: its own if it exists, else as `open` would create it (umask)."""
    if path.exists():
        return path.stat().st_mode & 0o777
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def write_atomic_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as temporary:
        temporary.write_bytes(data)


def write_atomic_text(path: str | Path, text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    write_atomic_bytes(path, text.encode("utf-8"))


def write_atomic_files(folder: str | Path, contents: Mapping[str, str | bytes]) -> None:
    """Write several files in ``folder`` as a set: all of them, or none.

    Every file is written to its temporary file first; only when all are written are they
    renamed over their names, so a failure while writing (a full disk, a size limit) leaves
    every file as it was, and its error names the file that could not be written.

    Parameters
    ----------
    folder
        The folder, which must exist.
    contents
        Each file's name in ``folder`` and its content: bytes, or text written as UTF-8.
    """
    with ExitStack() as stack:
        paths = {name: Path(folder) / name for name in contents}
        temporaries = {name: stack.enter_context(atomic_path(paths[name])) for name in contents}
        for name, content in contents.items():
            data = content.encode("utf-8") if isinstance(content, str) else content
            try:
                temporaries[name].write_bytes(data)
            except OSError as error:
                raise naming(error, paths[name]) from error


def write_atomic_json(path: str | Path, value: Any) -> None:
    """Write ``json_safe(value)`` to ``path`` atomically, indented, with a final newline."""
    write_atomic_text(path, json_text(value))


def json_text(value: Any) -> str:
    """Return ``json_safe(value)`` as JSON text, indented, with a final newline."""
    return json.dumps(json_safe(value), indent=2) + "\n"


def json_safe(value: Any) -> Any:
    """Plain JSON values: numpy scalars and arrays converted, NaN and infinities as ``None``."""
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        return json_safe(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def csv_text(frame: pd.DataFrame, **options: Any) -> str:
    """Return ``frame`` as CSV text (`pandas.DataFrame.to_csv` with ``options``), safe to open.

    A text cell (a value, column name or index label) that starts with one of `FORMULA_STARTS`
    gets `TEXT_MARK` before it (OWASP's rule against CSV injection), and so does one that starts
    with the mark itself: a spreadsheet shows the text as given, never runs it as a formula, and
    `csv_cells` reads it back unchanged. Numbers are written as they are. A table with a carriage
    return inside a text cell ends its lines with CR LF (RFC 4180), so that the cell is quoted
    and stays one cell (Python's CSV writer quotes only the line end's characters).
    """
    safe = frame.rename(columns=_marked, index=_marked)
    text = safe.select_dtypes(include=["object", "string"]).columns
    safe[text] = safe[text].map(_marked)
    returns = any("\r" in str(label) for label in [*safe.columns, *safe.index]) or any(
        isinstance(value, str) and "\r" in value for value in safe[text].to_numpy().ravel()
    )
    buffer = io.StringIO()
    safe.to_csv(buffer, lineterminator="\r\n" if returns else None, **options)
    return buffer.getvalue()


def csv_cells(frame: pd.DataFrame) -> pd.DataFrame:
    """Return a table read from `csv_text`'s CSV with its text cells as they were given."""
    plain = frame.rename(columns=_unmarked)
    text = plain.select_dtypes(include=["object", "string"]).columns
    plain[text] = plain[text].map(_unmarked)
    return plain


def _marked(value: Any) -> Any:
    if isinstance(value, str) and value.startswith((*FORMULA_STARTS, TEXT_MARK)):
        return TEXT_MARK + value
    return value


def _unmarked(value: Any) -> Any:
    return value.removeprefix(TEXT_MARK) if isinstance(value, str) else value
