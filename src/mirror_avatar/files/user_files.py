"""The one way files a user names are opened: regular files only, read within a bound.

A path from the command line, a player spec or a lab plan may name anything: a named pipe (FIFO)
whose reader waits for ever for a writer, a device that never ends (``/dev/zero``), a socket, a
folder, a path with a NUL byte or a part longer than the system allows. `open_regular` refuses
all of these in one `InputError` line before any byte is read:

- the path is checked first (`check_path`): no NUL byte, no part over `MAX_PART_BYTES` bytes;
- the file is looked at with ``stat`` (which never blocks) and refused unless it is a regular file
  of at most the reader's size limit, then opened without blocking (``O_NONBLOCK``, so a file
  swapped for a FIFO in between cannot hold the open), and looked at again on the open handle
  (``fstat``), which is what is read;
- `read_bytes` and `read_text` then read at most the limit (and one byte more, to notice a file
  that grew past it).

JSON and TOML a user gives (sidecars, session descriptions, graphs, model metadata, study
protocols, data dictionaries, request bodies) are parsed by `parse_json` and `parse_toml`, which
bound their nesting to `MAX_DEPTH` levels in one way (`bounded`): the text is parsed, a parser
that exhausts Python's recursion limit is refused, and the value read is measured without
recursion and refused when deeper than the limit. The value is measured rather than the text
pre-scanned because TOML nests without brackets (dotted keys, ``[a.b.c]`` headers, quoted keys
with dots), which only the parser reads right; whatever reads the value after (checks, error
lines naming it) never recurses deeper than `MAX_DEPTH`. `parse_json` also refuses numbers JSON
cannot hold (NaN, Infinity, or a value beyond float64's range, which Python would read as
infinite).
"""

from __future__ import annotations

import json
import math
import os
import stat
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any, TypeGuard, TypeVar

from mirror_avatar.common.errors import InputError

MAX_PART_BYTES = 255
"""Longest part of a path, in bytes of its file-system encoding (``NAME_MAX`` of Linux, macOS
and Windows file systems)."""

MAX_DEPTH = 32
"""Deepest nesting of arrays, objects and tables in JSON or TOML a user gives (**choice**: the
deepest the package writes is 4, a study protocol's is 7)."""

KINDS = {
    stat.S_IFDIR: "a folder",
    stat.S_IFIFO: "a named pipe (FIFO)",
    stat.S_IFCHR: "a character device",
    stat.S_IFBLK: "a block device",
    stat.S_IFSOCK: "a socket",
}
"""What each kind of file that is not a regular file is called in an error line."""

Parsed = TypeVar("Parsed")

FLOAT_DIGITS = 308
"""Most digits of a JSON integer read: larger ones are beyond float64's range (about 1.8e308)."""


def check_path(path: str | os.PathLike[str]) -> Path:
    """Return ``path`` as a `Path` if the system could open it: no NUL byte, short parts.

    Raises
    ------
    InputError
        A NUL byte in the path, or a part longer than `MAX_PART_BYTES` bytes.
    """
    text = os.fspath(path)
    shown = text.replace("\0", "\\0")
    if len(shown) > 120:
        shown = f"{shown[:60]}...{shown[-40:]}"
    if "\0" in text:
        raise InputError(shown, "the path holds a NUL byte; no file can be named so")
    for part in Path(text).parts:
        size = len(os.fsencode(part))
        if size > MAX_PART_BYTES:
            raise InputError(
                shown, f"a part of the path is {size} bytes, over the {MAX_PART_BYTES} a file name "
                "may have",
            )  # fmt: skip
    return Path(text)


def file_kind(mode: int) -> str:
    """Name the kind of file ``mode`` (from ``stat``) describes, for an error line."""
    return KINDS.get(stat.S_IFMT(mode), "not a regular file")


def _refuse_status(path: Path, status: os.stat_result, limit: int) -> None:
    """Refuse a file whose status is not a regular file of at most ``limit`` bytes."""
    if not stat.S_ISREG(status.st_mode):
        raise InputError(path, f"is {file_kind(status.st_mode)}, not a regular file")
    if status.st_size > limit:
        raise InputError(path, f"{status.st_size:,} bytes, over the limit {size_limit(limit)}")


def size_limit(limit: int) -> str:
    """Describe a byte limit for an error line: exact, and in MiB."""
    return f"of {limit:,} bytes ({limit / 2**20:g} MiB) for files read"


def _os_problem(path: Path, error: OSError) -> InputError:
    """Turn the failure to look at or open ``path`` into one line."""
    if isinstance(error, FileNotFoundError):
        return InputError(path, "no such file")
    return InputError(path, f"cannot be read ({error.strerror or type(error).__name__})")


def check_regular(path: str | os.PathLike[str], limit: int) -> int:
    """Check ``path`` is a regular file of at most ``limit`` bytes, without opening it.

    Returns
    -------
    int
        Its size (bytes).

    Raises
    ------
    InputError
        A bad path (`check_path`), a missing or unreadable file, a file that is not a regular
        file (folder, FIFO, device, socket), or one over ``limit`` bytes.
    """
    checked = check_path(path)
    try:
        status = checked.stat()
    except OSError as error:
        raise _os_problem(checked, error) from None
    _refuse_status(checked, status, limit)
    return status.st_size


def open_regular(path: str | os.PathLike[str], limit: int) -> IO[bytes]:
    """Open ``path`` for reading in binary if it is a regular file of at most ``limit`` bytes.

    The file is checked (`check_regular`), opened without blocking and checked again on the
    handle, so what is read is what was checked. The caller closes the handle (``with``).

    Raises
    ------
    InputError
        As `check_regular`.
    """
    checked = Path(path)
    check_regular(checked, limit)
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_BINARY", 0)
    try:
        descriptor = os.open(checked, flags)
    except OSError as error:
        raise _os_problem(checked, error) from None
    try:
        _refuse_status(checked, os.fstat(descriptor), limit)
        os.set_blocking(descriptor, True)
    except BaseException:
        os.close(descriptor)
        raise
    return os.fdopen(descriptor, "rb")


def read_bytes(path: str | os.PathLike[str], limit: int) -> bytes:
    """Read a whole regular file of at most ``limit`` bytes (see `open_regular`).

    Raises
    ------
    InputError
        As `open_regular`, or the file grew past ``limit`` while it was read.
    """
    with open_regular(path, limit) as handle:
        try:
            data = handle.read(limit + 1)
        except OSError as error:
            raise _os_problem(Path(path), error) from None
    if len(data) > limit:
        raise InputError(path, f"over the limit {size_limit(limit)}")
    return data


def read_text(path: str | os.PathLike[str], limit: int) -> str:
    """Read a UTF-8 text file of at most ``limit`` bytes; a byte-order mark is dropped.

    Raises
    ------
    InputError
        As `read_bytes`, or not UTF-8.
    """
    try:
        return read_bytes(path, limit).decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(path, "not UTF-8 text (save it as UTF-8)") from None


def nesting_depth(value: object) -> int:
    """Return how many lists and dicts nest in ``value`` (0 for a scalar), without recursion."""
    deepest, pending = 0, [(value, 0)]
    while pending:
        item, depth = pending.pop()
        if isinstance(item, dict):
            item = list(item.values())
        if isinstance(item, list):
            deepest = max(deepest, depth + 1)
            pending.extend((child, depth + 1) for child in item)
    return deepest


def bounded(
    load: Callable[[], Parsed], source: str | os.PathLike[str] | None, subject: str
) -> Parsed:
    """Return what ``load`` parses, refused when nested deeper than `MAX_DEPTH` levels.

    Parameters
    ----------
    load
        Parses the text (its own syntax errors are its to report).
    source
        Where the text comes from (a file path), named in errors.
    subject
        What the text is, as the error line says it (e.g. ``"is TOML"``).

    Raises
    ------
    InputError
        The parser exhausted Python's recursion limit, or the value read nests deeper than
        `MAX_DEPTH` levels (`nesting_depth`).
    """
    too_deep = InputError(source, f"{subject} nested deeper than the limit of {MAX_DEPTH} levels")
    try:
        value = load()
    except RecursionError:
        raise too_deep from None
    if nesting_depth(value) > MAX_DEPTH:
        raise too_deep
    return value


def _finite(text: str) -> float:
    """Parse a JSON number with a fraction or exponent, refusing one beyond float64's range."""
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"the number {text[:20]} is beyond the range of float64")
    return value


def is_int(value: object) -> TypeGuard[int]:
    """Whether a parsed JSON or TOML value is an integer (``true`` is not: a bool is no integer)."""
    return isinstance(value, int) and not isinstance(value, bool)


def _integer(text: str) -> int:
    """Parse a JSON integer, refusing one beyond float64's range (it could not become a float)."""
    if len(text.lstrip("-")) > FLOAT_DIGITS:
        raise ValueError(f"the number {text[:20]}... is beyond the range of float64")
    return int(text)


def _no_constant(name: str) -> float:
    """Refuse ``NaN``, ``Infinity`` and ``-Infinity``, which Python's JSON reader accepts."""
    raise ValueError(f"{name} is not a JSON number")


def parse_json(
    text: str | bytes,
    source: str | os.PathLike[str] | None,
    what: str = "",
    finite: bool = True,
) -> Any:
    """Parse JSON a user gave, nested at most `MAX_DEPTH` deep (`bounded`), with finite numbers.

    Parameters
    ----------
    text
        The JSON text (bytes are decoded as UTF-8).
    source
        Where it comes from (a file path), named in errors.
    what
        What it is within ``source`` (e.g. ``"metadata"``), named in errors; empty for the
        whole file.
    finite
        Refuse ``NaN`` and ``Infinity`` (not JSON, but Python writes them) and numbers beyond
        float64's range; False for texts whose every value is range-checked by its reader
        (model metadata), which then names the value's key.

    Raises
    ------
    InputError
        Not UTF-8, not JSON, nested too deeply, or a number that is NaN, infinite or beyond
        float64's range.
    """
    subject = f"{what} is" if what else "is"
    try:
        decoded = text.decode("utf-8-sig") if isinstance(text, bytes) else text
    except UnicodeDecodeError:
        raise InputError(source, f"{subject} not UTF-8 text") from None
    return bounded(lambda: _json_value(decoded, source, subject, finite), source, f"{subject} JSON")


def _json_value(
    text: str, source: str | os.PathLike[str] | None, subject: str, finite: bool
) -> Any:
    """Parse a JSON text for `parse_json`, refusing its syntax and, if ``finite``, its numbers."""
    try:
        if not finite:
            return json.loads(text)
        return json.loads(
            text, parse_float=_finite, parse_int=_integer, parse_constant=_no_constant
        )
    except json.JSONDecodeError as error:
        raise InputError(
            source, f"{subject} not valid JSON ({error.msg} at line {error.lineno})"
        ) from None
    except ValueError as error:
        raise InputError(source, f"{subject} not valid JSON ({error})") from None


def parse_toml(text: str, source: str | os.PathLike[str]) -> dict[str, Any]:
    """Parse TOML a user gave (a study protocol), nested at most `MAX_DEPTH` deep (`bounded`).

    Raises
    ------
    InputError
        ``SOURCE: not valid TOML: ...`` with where the syntax fails, or nested too deeply.
    """
    return bounded(lambda: _toml_table(text, source), source, "is TOML")


def _toml_table(text: str, source: str | os.PathLike[str]) -> dict[str, Any]:
    """Parse a TOML text for `parse_toml`, refusing its syntax in one line."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise InputError(source, f"not valid TOML: {error} (fix the syntax there)") from None


def read_json(path: str | os.PathLike[str], limit: int) -> Any:
    """Read a JSON file of at most ``limit`` bytes with `parse_json`.

    Raises
    ------
    InputError
        As `read_text` and `parse_json`.
    """
    return parse_json(read_text(path, limit), path)
