"""Model files: one ``.npz`` archive of arrays plus a JSON metadata string, never pickled.

Every saved model (IMS generator, cyber player) is written atomically by `save_model` and read
back by `load_model`, which checks the format name and version in the metadata and turns every
way a file can be wrong (missing, truncated, not an archive, another format, bad JSON, hostile
content) into one `InputError` line naming the file.

A model file may come from anyone, so `read_archive` reads nothing it has not bounded first
(every limit is a **choice**, far above what a real model needs; see each constant):

- the zip's central directory may declare at most `MAX_DIRECTORY_BYTES`, checked on the end
  records before `zipfile` lists the members, and it may list at most `MAX_MEMBERS` members;
- each member must be a ``.npy`` array, stored or deflated (as numpy writes them; other
  compression methods can expand a small read without bound) and not encrypted; its declared
  uncompressed size may be at most `MAX_MEMBER_BYTES`, and all members together at most
  `MAX_TOTAL_BYTES`;
- each member's ``.npy`` header is read before its data: the dtype must be integer or floating
  point (the ``metadata`` member: one unicode string of at most `MAX_METADATA_CHARS`
  characters), and the shape times the item size must equal the declared size;
- the archive must be a regular file of at most `MAX_FILE_BYTES`
  (`mirror_avatar.files.user_files.open_regular`: a named pipe or a device is refused unopened);
- the metadata JSON is parsed by `mirror_avatar.files.user_files.parse_json`: at most
  `mirror_avatar.files.user_files.MAX_DEPTH` arrays and objects deep.

The loaders then check every value they read with `check_integer`, `check_real`, `check_array`
(every array value finite and at most `MAX_MAGNITUDE` in size unless a tighter range is given)
and `check_object`; a value quoted in a message is cut by `mirror_avatar.files.importing.excerpt`.
"""

from __future__ import annotations

import io
import json
import math
import numbers
import os
import struct
import zipfile
import zlib
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import IO, Any, Literal

import numpy as np
from numpy.typing import NDArray

from mirror_avatar import __version__
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import write_atomic_bytes
from mirror_avatar.files.importing import excerpt
from mirror_avatar.files.user_files import open_regular, parse_json

PathLike = str | os.PathLike[str]
Source = str | os.PathLike[str] | None
ZIP_MAGIC = b"PK\x03\x04"
"""The first bytes of every ``.npz`` archive (a zip file)."""

MAX_MEMBERS = 32
"""Most members a model archive may hold (**choice**: a cyber player with its reference
generator has 9)."""

MAX_DIRECTORY_BYTES = 256 * 1024
"""Largest central directory (the zip's list of members) a model archive may declare, in bytes
(**choice**: a model's few members take well under 4 KiB; this bounds the work of listing a
crafted archive before `MAX_MEMBERS` can be checked)."""

MAX_MEMBER_BYTES = 256 * 1024**2
"""Largest declared uncompressed size of one member, in bytes (**choice**: the largest default
Q-table takes 0.7 MB)."""

MAX_TOTAL_BYTES = 512 * 1024**2
"""Largest declared uncompressed size of all members together, in bytes (**choice**)."""

MAX_METADATA_CHARS = 1_000_000
"""Longest metadata JSON string, in characters (**choice**: a model's metadata takes a few
kilobytes)."""

MAX_FILE_BYTES = MAX_TOTAL_BYTES + 2**24
"""Largest model archive read, in bytes: `MAX_TOTAL_BYTES` and 16 MiB for the zip's own records
(**choice**)."""

MAX_MAGNITUDE = 1e9
"""Largest magnitude of a value in a model's arrays (`check_array`'s default range; **choice**:
trained weights, Q values, counts and velocities stay orders of magnitude below, while a deep
network of the largest layout `mirror_avatar.deep.player` reads, nine layers of at most 1024
inputs, with weights this large still computes finite values, about 1e113 times its input)."""

MEMBER_DATE = (1980, 1, 1, 0, 0, 0)
"""Date and time given to every member of a saved archive (the earliest a zip file can hold)."""

Kind = Literal["float", "integer", "number"]
_KINDS: dict[Kind, str] = {"float": "f", "integer": "iu", "number": "iuf"}
"""numpy dtype kinds of each kind of array; members of any other kind are refused."""

_END = struct.Struct("<4s4H2LH")
_END_SIGNATURE = b"PK\x05\x06"
_ZIP64_LOCATOR_SIGNATURE = b"PK\x06\x07"
_ZIP64_END_SIGNATURE = b"PK\x06\x06"
_ZIP64_LOCATOR = struct.Struct("<4sLQL")
_ZIP64_END = struct.Struct("<4sQ2H2L4Q")
_TAIL_BYTES = _ZIP64_END.size + _ZIP64_LOCATOR.size + _END.size + 0xFFFF
"""Bytes at the end of an archive that hold its end records (the end record may be followed by
a comment of up to 64 KiB and preceded by the zip64 locator and record)."""

_CHAR_BYTES = np.dtype("U1").itemsize
"""Bytes per character of a numpy unicode string."""


def save_model(
    path: PathLike,
    format_name: str,
    version: int,
    arrays: dict[str, NDArray[Any]],
    metadata: dict[str, Any],
) -> Path:
    """Write ``arrays`` and ``metadata`` to ``path`` atomically.

    The archive is what `numpy.savez` writes, except that every member carries the same date
    (`MEMBER_DATE`), so that one model saved twice gives the same bytes.

    Parameters
    ----------
    path
        Destination ``.npz`` file; its directory is created if needed.
    format_name, version
        Stored in the metadata as ``format`` and ``version`` and checked on loading.
    arrays
        Named numeric arrays.
    metadata
        JSON-serialisable description (parameters, training summary, seeds).

    Returns
    -------
    Path
        The path written.
    """
    header = {"format": format_name, "version": version, "library_version": __version__}
    buffer = io.BytesIO()
    contents = {"metadata": np.array(json.dumps({**header, **metadata})), **arrays}
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
        for name, array in contents.items():
            member = zipfile.ZipInfo(f"{name}.npy", date_time=MEMBER_DATE)
            member.external_attr = 0o600 << 16
            with archive.open(member, "w", force_zip64=True) as stream:
                np.lib.format.write_array(stream, np.asanyarray(array), allow_pickle=False)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic_bytes(path, buffer.getvalue())
    return path


def read_archive(path: PathLike) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
    """Read any model archive: its arrays and its metadata, without checking the format.

    Every limit of the module docstring is checked before the data it bounds is read.

    Raises
    ------
    InputError
        Missing file, not a readable ``.npz`` archive, an archive beyond the limits, or
        metadata that is not a JSON object.
    """
    try:
        with open_regular(path, MAX_FILE_BYTES) as file:
            if file.read(4) != ZIP_MAGIC:
                raise InputError(path, "not a readable .npz model file (not a zip archive)")
            directory = _declared_directory_size(file)
            if directory > MAX_DIRECTORY_BYTES:
                raise InputError(
                    path,
                    f"the zip directory declares {directory} bytes, more than the limit of "
                    f"{MAX_DIRECTORY_BYTES}",
                )
            with zipfile.ZipFile(file) as archive:
                arrays = _read_members(path, archive)
    except InputError:
        raise
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as error:
        raise InputError(
            path, f"not a readable .npz model file ({excerpt(str(error), quote=False)})"
        ) from None
    if "metadata" not in arrays:
        raise InputError(path, "not a mirror-avatar model file (no metadata)")
    metadata = parse_json(str(arrays.pop("metadata")[()]), path, "metadata", finite=False)
    if not isinstance(metadata, dict):
        raise InputError(path, "metadata is not a JSON object")
    return arrays, metadata


def _declared_directory_size(file: IO[bytes]) -> int:
    """Size (bytes) of the central directory an archive's end records declare.

    The end record is found as `zipfile` finds it (at the very end of the file, else the last
    one in the final 64 KiB); the largest of its size and those of any zip64 end record it
    points to is returned, so `zipfile` never reads a larger directory.

    Raises
    ------
    zipfile.BadZipFile
        No end record.
    """
    end = file.seek(0, os.SEEK_END)
    start = file.seek(max(end - _TAIL_BYTES, 0))
    tail = file.read()
    at = len(tail) - _END.size
    if not (at >= 0 and tail.startswith(_END_SIGNATURE, at) and tail.endswith(b"\0\0")):
        at = tail.rfind(_END_SIGNATURE)
    if at < 0 or at + _END.size > len(tail):
        raise zipfile.BadZipFile("no end of central directory record")
    sizes = [_END.unpack_from(tail, at)[5]]
    locator = at - _ZIP64_LOCATOR.size
    if locator >= 0 and tail.startswith(_ZIP64_LOCATOR_SIGNATURE, locator):
        offset = _ZIP64_LOCATOR.unpack_from(tail, locator)[2]
        for position in (max(start + locator - _ZIP64_END.size, 0), min(offset, end)):
            file.seek(position)
            record = file.read(_ZIP64_END.size)
            if len(record) == _ZIP64_END.size and record.startswith(_ZIP64_END_SIGNATURE):
                sizes.append(_ZIP64_END.unpack(record)[8])
    return max(sizes)


def _read_members(path: PathLike, archive: zipfile.ZipFile) -> dict[str, NDArray[Any]]:
    """Check the members' number, names and declared sizes, then each header, then read."""
    members = archive.infolist()
    if len(members) > MAX_MEMBERS:
        raise InputError(path, f"{len(members)} members, more than the limit of {MAX_MEMBERS}")
    names = [_member_name(path, member) for member in members]
    total = sum(member.file_size for member in members)
    if total > MAX_TOTAL_BYTES:
        raise InputError(
            path, f"members declare {total} bytes in all, more than the limit of {MAX_TOTAL_BYTES}"
        )
    duplicate = next((name for name in names if names.count(name) > 1), None)
    if duplicate is not None:
        raise InputError(path, f"member {excerpt(duplicate, quote=False)} appears more than once")
    arrays = {}
    for name, member in zip(names, members, strict=True):
        with archive.open(member) as stream:
            _check_header(path, name, member.file_size, stream)
            stream.seek(0)
            arrays[name] = np.lib.format.read_array(stream, allow_pickle=False)
    return arrays


def _member_name(path: PathLike, member: zipfile.ZipInfo) -> str:
    """Return the array name of a member (without ``.npy``) once its zip entry is acceptable."""
    name = excerpt(member.filename, quote=False)
    if not member.filename.endswith(".npy"):
        raise InputError(path, f"member {name} is not a .npy array")
    if member.flag_bits & 0x1:
        raise InputError(path, f"member {name} is encrypted")
    if member.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        method = member.compress_type
        raise InputError(
            path, f"member {name} uses compression method {method}, not stored or deflated"
        )
    if member.file_size > MAX_MEMBER_BYTES:
        raise InputError(
            path,
            f"member {name} declares {member.file_size} bytes, more than the limit of "
            f"{MAX_MEMBER_BYTES}",
        )
    return member.filename.removesuffix(".npy")


def _check_header(path: PathLike, name: str, declared: int, stream: IO[bytes]) -> None:
    """Refuse a member whose ``.npy`` header is not a numeric array of its declared size."""
    shown = excerpt(name, quote=False)
    version = np.lib.format.read_magic(stream)
    if version == (1, 0):
        shape, _, dtype = np.lib.format.read_array_header_1_0(stream)
    elif version == (2, 0):
        shape, _, dtype = np.lib.format.read_array_header_2_0(stream)
    else:
        raise InputError(path, f"member {shown} has unsupported .npy version {version}")
    if name == "metadata":
        if dtype.kind != "U" or shape != ():
            raise InputError(path, "metadata is not one JSON string")
        length = dtype.itemsize // _CHAR_BYTES
        if length > MAX_METADATA_CHARS:
            raise InputError(
                path,
                f"metadata of {length} characters is longer than the limit of {MAX_METADATA_CHARS}",
            )
    elif dtype.kind not in _KINDS["number"]:
        raise InputError(
            path, f"{shown} has dtype {excerpt(dtype)}; model arrays hold integers or floats"
        )
    size = math.prod(shape) * dtype.itemsize
    if size > MAX_MEMBER_BYTES:
        raise InputError(
            path,
            f"{shown} has a header claiming {excerpt(size)} bytes, more than the limit of "
            f"{MAX_MEMBER_BYTES}",
        )
    if stream.tell() + size != declared:
        raise InputError(
            path,
            f"{shown} has a header claiming {size} bytes of data but holds "
            f"{declared - stream.tell()}",
        )


def load_model(
    path: PathLike, format_name: str, version: int, required: tuple[str, ...]
) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
    """Read a model written by `save_model` and check its format, version and arrays.

    Parameters
    ----------
    path
        The ``.npz`` file.
    format_name, version
        What the file must be.
    required
        Names of the arrays it must hold.

    Returns
    -------
    arrays, metadata
        The arrays (without ``metadata``) and the decoded metadata.

    Raises
    ------
    InputError
        Any problem with the file, in one line naming it.
    """
    arrays, metadata = read_archive(path)
    if metadata.get("format") != format_name:
        raise InputError(
            path, f"not a {format_name} file (format {excerpt(metadata.get('format'))})"
        )
    if metadata.get("version") != version:
        raise InputError(
            path, f"unsupported {format_name} version {excerpt(metadata.get('version'))}"
        )
    require_arrays(path, arrays, required)
    return arrays, metadata


PART_SEPARATOR = "__"
"""Joins a part's name and an array's name in an archive of several models (`join_parts`)."""


def join_parts(parts: Mapping[str, Mapping[str, NDArray[Any]]]) -> dict[str, NDArray[Any]]:
    """Merge several models' arrays into one archive: ``PART__NAME`` for each part's array."""
    return {
        f"{part}{PART_SEPARATOR}{name}": array
        for part, arrays in parts.items()
        for name, array in arrays.items()
    }


def part_arrays(arrays: Mapping[str, NDArray[Any]], part: str) -> dict[str, NDArray[Any]]:
    """Return one part's arrays of an archive written with `join_parts`, by their own names."""
    prefix = f"{part}{PART_SEPARATOR}"
    return {k.removeprefix(prefix): a for k, a in arrays.items() if k.startswith(prefix)}


def require_arrays(source: Source, arrays: Mapping[str, Any], names: Iterable[str]) -> None:
    """Refuse ``arrays`` if some of ``names`` are missing."""
    missing = sorted(set(names) - arrays.keys())
    if missing:
        raise InputError(source, f"missing array(s) {', '.join(missing)}")


def _bounds(low: float, high: float) -> str:
    return "..".join(str(b) if isinstance(b, int) else f"{b:g}" for b in (low, high))


def check_integer(source: Source, name: str, value: object, low: float, high: float) -> int:
    """Return ``value`` as an int if it is a whole number in [low, high].

    Parameters
    ----------
    source
        What the value was read from (a file path), named by the message.
    name
        The value's name in the message.
    value
        Anything read from input; an integral float (3.0) counts as a whole number.
    low, high
        The accepted range, inclusive.

    Raises
    ------
    InputError
        ``source: name VALUE is outside LOW..HIGH``, or ``name must be an integer``.
    """
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputError(source, f"{name} must be an integer, not {excerpt(value)}")
    number = int(value)
    _check_within(source, name, number, low, high)
    return number


def check_real(source: Source, name: str, value: object, low: float, high: float) -> float:
    """Return ``value`` as a float if it is a number in [low, high] (NaN never is).

    Parameters are those of `check_integer`.

    Raises
    ------
    InputError
        ``source: name VALUE is outside LOW..HIGH``, or ``name must be a number``.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(source, f"{name} must be a number, not {excerpt(value)}")
    number = value if isinstance(value, int) else float(value)
    _check_within(source, name, number, low, high)
    return float(number)


def _check_within(source: Source, name: str, number: float, low: float, high: float) -> None:
    """Refuse ``number`` unless it lies in [low, high] (a huge int is compared exactly)."""
    if not low <= number <= high:
        raise InputError(source, f"{name} {excerpt(number)} is outside {_bounds(low, high)}")


def check_array(
    source: Source,
    name: str,
    array: NDArray[Any],
    kind: Kind,
    shape: tuple[int | None, ...],
    low: float = -MAX_MAGNITUDE,
    high: float = MAX_MAGNITUDE,
) -> NDArray[Any]:
    """Return ``array`` if its dtype kind, shape and values are as expected.

    Parameters
    ----------
    source
        What the array was read from (a file path), named by the message.
    name
        The array's name in the message.
    array
        The array read.
    kind
        ``"float"``, ``"integer"`` or ``"number"`` (either); other dtypes are refused.
    shape
        The expected shape; None matches any length along that axis.
    low, high
        Every value must be finite and lie in [low, high] (default ±`MAX_MAGNITUDE`).

    Raises
    ------
    InputError
        One line naming the array and what is wrong with it.
    """
    if array.dtype.kind not in _KINDS[kind]:
        raise InputError(source, f"{name} has dtype {array.dtype}, expected {kind}s")
    if array.ndim != len(shape) or any(
        want is not None and want != got for want, got in zip(shape, array.shape, strict=True)
    ):
        wanted = f"{len(shape)}-D" if None in shape else str(shape)
        raise InputError(source, f"{name} has shape {excerpt(array.shape)}, expected {wanted}")
    bad = ~np.isfinite(array) | (array < low) | (array > high)
    if np.any(bad):
        value = array.flat[int(np.argmax(bad))]
        raise InputError(
            source,
            f"{name} holds {excerpt(value)}; its values must be finite and within "
            f"{_bounds(low, high)}",
        )
    return array


def check_object(source: Source, name: str, value: object) -> dict[str, Any]:
    """Return ``value`` if it is a JSON object (a dict), else refuse it naming ``name``."""
    if not isinstance(value, dict):
        raise InputError(source, f"{name} must be a JSON object, not {excerpt(value)}")
    return value
