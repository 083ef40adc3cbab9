"""A structural check of MATLAB v5 files, before SciPy reads them.

SciPy's ``loadmat`` trusts what it reads: a damaged data-type code inside an array can crash the
interpreter (a segmentation fault, not an exception), compressed variables are inflated whole,
and cell and struct arrays are built element by element as their dimensions state. `mat_problem`
walks a file's elements as SciPy will read them (MathWorks, *MAT-File Format*, level 5) and names
the first problem, without keeping any variable's data. It checks the structure only; SciPy still
reads the values and raises for problems this check leaves to it.

Each top-level cell or struct array is a list of trials, and every trial read is later resampled
over its whole duration (a few bytes in the file can become a minute of samples), so the number
of its elements is bounded by the caller (``max_elements``). It is read from the array's header,
first, before the variable is walked or inflated: a file of a hundred thousand trials is refused
after reading a few hundred bytes of it.
"""

from __future__ import annotations

import math
import mmap
import struct
import zlib
from typing import IO

NUMBER_TYPES = frozenset({1, 2, 3, 4, 5, 6, 7, 9, 12, 13})
"""Data-type codes of numbers (miINT8 ... miUINT64): the values of numeric arrays."""

TEXT_TYPES = NUMBER_TYPES | {16, 17, 18}
"""Data-type codes a character array's values may have (numbers and miUTF8 ... miUTF32)."""

MATRIX, COMPRESSED = 14, 15
"""Data-type codes of an array (miMATRIX) and of a zlib-compressed variable (miCOMPRESSED)."""

CELL, STRUCT, CHAR = 1, 2, 4
"""Array classes with their own layout (mxCELL, mxSTRUCT, mxCHAR)."""

NUMERIC = frozenset(range(6, 16))
"""Numeric array classes (mxDOUBLE ... mxUINT64). Objects, sparse arrays, function handles and
opaque classes are refused: a trial file holds none."""

MAX_DEPTH = 32
"""Deepest nesting of cells and structs read (**choice**)."""

MAX_DIMS = 32
"""Most dimensions of an array read (**choice**)."""

INFLATE_CHUNK = 2**20
"""Bytes inflated at a time when counting what a compressed variable inflates to."""

HEAD_BYTES = 256
"""Bytes of a variable holding its array header (tag, flags and up to `MAX_DIMS` dimensions)."""

HEAD_INPUT_BYTES = 2**16
"""Most compressed bytes inflated to read a compressed variable's header."""


class DamagedFile(Exception):
    """A MATLAB file's structure is damaged; the message says how, for an error line."""


class TooManyElements(Exception):
    """A top-level cell or struct array has more elements than the caller reads.

    Parameters
    ----------
    count
        Its number of elements.
    """

    def __init__(self, count: int) -> None:
        super().__init__(f"{count} elements")
        self.count = count


def mat_problem(handle: IO[bytes], limit: int, max_elements: int) -> str:
    """Name the first structural problem of a MATLAB v5 file, or return ``""``.

    Parameters
    ----------
    handle
        The file, open for reading in binary (`mirror_avatar.files.user_files.open_regular`); one
        that
        is not a level-5 MAT-file (a v4 file, text) is left to SciPy (``""``).
    limit
        Most bytes all compressed variables may inflate to, together.
    max_elements
        Most elements a top-level cell or struct array may have (trials).

    Raises
    ------
    TooManyElements
        A top-level cell or struct array has more than ``max_elements`` elements.
    OSError
        The file cannot be read.
    """
    handle.seek(0)
    header = handle.read(128)
    order = {b"IM": "<", b"MI": ">"}.get(header[126:128])
    if (
        len(header) < 128
        or order is None
        or struct.unpack_from(order + "H", header, 124)[0] != 0x0100
    ):
        return ""
    with mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ) as data:
        try:
            _walk_variables(data, order, limit, max_elements)
        except (DamagedFile, zlib.error, struct.error) as error:
            return str(error) or type(error).__name__
    return ""


def _walk_variables(data: mmap.mmap, order: str, limit: int, max_elements: int) -> None:
    """Walk every top-level variable of a v5 file, inflating compressed ones within ``limit``.

    The element count of each is checked against ``max_elements`` (`_check_elements`) first.
    """
    inflated, position = 0, 128
    while position + 8 <= len(data):
        kind, length = _tag(data, position, order)
        start, end = position + 8, position + 8 + length
        if end > len(data):
            raise DamagedFile("it is truncated")
        if kind == COMPRESSED:
            head = zlib.decompressobj().decompress(
                data[start : min(end, start + HEAD_INPUT_BYTES)], HEAD_BYTES
            )
        else:
            head = data[position : min(end, position + HEAD_BYTES)]
        _check_elements(head, order, max_elements)
        if kind == COMPRESSED:
            inflated += _inflated_size(data, start, end, limit - inflated)
            if inflated > limit:
                raise DamagedFile(f"its compressed variables inflate to over {limit:,} bytes")
            _walk_array(zlib.decompress(data[start:end]), 0, order, 0)
        else:
            _walk_array(data, position, order, 0)
        position = end + (-length % 8 if kind != COMPRESSED else 0)


def _check_elements(head: bytes, order: str, max_elements: int) -> None:
    """Refuse a top-level cell or struct array of more than ``max_elements`` elements.

    ``head`` holds the start of the variable; a header it does not hold whole is left to the
    walk, which names the damage.
    """
    try:
        kind, _ = _tag(head, 0, order)
        if kind != MATRIX:
            return
        array_class, _, count, _ = _array_header(head, 0, order)
    except (DamagedFile, struct.error):
        return
    if array_class in (CELL, STRUCT) and count > max_elements:
        raise TooManyElements(count)


def _array_header(data: bytes | mmap.mmap, position: int, order: str) -> tuple[int, int, int, int]:
    """Read the flags and dimensions of the array (miMATRIX) at ``position``.

    Returns
    -------
    array_class, is_complex, count, name : int
        Its class, 1 if complex, its number of elements, and where its name element starts.
    """
    payload, size, position = _element(data, position + 8, order)
    if size != 8:
        raise DamagedFile("damaged array flags")
    flags = struct.unpack_from(order + "I", data, payload)[0]
    array_class, is_complex = flags & 0xFF, flags >> 11 & 1
    if array_class not in NUMERIC | {CELL, STRUCT, CHAR}:
        raise DamagedFile(f"an array of class {array_class} (objects, sparse, handles...)")
    payload, size, position = _element(data, position, order)
    if size % 4 or not 0 < size <= 4 * MAX_DIMS:
        raise DamagedFile(f"damaged array dimensions (at most {MAX_DIMS})")
    dimensions = struct.unpack_from(f"{order}{size // 4}i", data, payload)
    if min(dimensions) < 0:
        raise DamagedFile("an array larger than the data that could fill it")
    return array_class, is_complex, math.prod(dimensions), position


def _inflated_size(data: mmap.mmap, start: int, end: int, budget: int) -> int:
    """Bytes the zlib stream ``data[start:end]`` inflates to, counted to just past ``budget``."""
    inflater, size = zlib.decompressobj(), 0
    for offset in range(start, end, INFLATE_CHUNK):
        pending = data[offset : min(offset + INFLATE_CHUNK, end)]
        while pending and size <= budget:
            size += len(inflater.decompress(pending, INFLATE_CHUNK))
            pending = inflater.unconsumed_tail
        if size > budget:
            break
    return size


def _tag(data: bytes | mmap.mmap, position: int, order: str) -> tuple[int, int]:
    """Return the data type and byte count of the full tag at ``position``."""
    if position + 8 > len(data):
        raise DamagedFile("it is truncated")
    kind, length = struct.unpack_from(order + "II", data, position)
    return int(kind), int(length)


def _element(
    data: bytes | mmap.mmap, position: int, order: str, types: frozenset[int] = NUMBER_TYPES
) -> tuple[int, int, int]:
    """Check the data element at ``position`` (a full or a small one) holds one of ``types``.

    Returns
    -------
    payload, size, end : int
        Where its data starts, its byte count, and where the next element starts.
    """
    kind, length = _tag(data, position, order)
    if kind >> 16:
        kind, length, payload, end = kind & 0xFFFF, kind >> 16, position + 4, position + 8
        if length > 4:
            raise DamagedFile("a damaged small data element")
    else:
        payload, end = position + 8, position + 8 + length + (-length % 8)
    if kind not in types:
        raise DamagedFile(f"an element of data type {kind} where numbers or text should be")
    if payload + length > len(data):
        raise DamagedFile("it is truncated")
    return payload, length, end


def _walk_array(data: bytes | mmap.mmap, position: int, order: str, depth: int) -> int:
    """Walk the array (miMATRIX) at ``position`` and everything it holds; return its end.

    Checks every element's data-type code, the array's class, that it has at most `MAX_DIMS`
    dimensions and no more elements than the bytes left could hold, and that cells and structs
    nest at most `MAX_DEPTH` deep.
    """
    kind, length = _tag(data, position, order)
    end = position + 8 + length
    if kind != MATRIX:
        raise DamagedFile(f"an element of type {kind} where an array should be")
    if end > len(data):
        raise DamagedFile("it is truncated")
    if length == 0:
        return end
    if depth > MAX_DEPTH:
        raise DamagedFile(f"arrays nested over {MAX_DEPTH} deep")
    array_class, is_complex, count, position = _array_header(data, position, order)
    if count > end - position:
        raise DamagedFile("an array larger than the data that could fill it")
    position = _element(data, position, order, TEXT_TYPES)[2]
    if array_class == CELL:
        children = count
    elif array_class == STRUCT:
        children, position = _struct_fields(data, position, order, count, end)
    else:
        types = TEXT_TYPES if array_class == CHAR else NUMBER_TYPES
        for _ in range(1 + is_complex):
            position = _element(data, position, order, types)[2]
        return end
    for _ in range(children):
        position = _walk_array(data, position, order, depth + 1)
    if position > end:
        raise DamagedFile("an array's contents run past its end")
    return end


def _struct_fields(
    data: bytes | mmap.mmap, position: int, order: str, count: int, end: int
) -> tuple[int, int]:
    """Check a struct's field names; return its number of field arrays and where they start."""
    payload, size, position = _element(data, position, order)
    width = struct.unpack_from(order + "i", data, payload)[0] if size == 4 else 0
    _, names, position = _element(data, position, order, TEXT_TYPES)
    if width <= 0 or names % width:
        raise DamagedFile("damaged struct field names")
    children = count * (names // width)
    if children * 8 > end - position:
        raise DamagedFile("a struct larger than the data that could fill it")
    return children, position
