"""Model files: one ``.npz`` archive of arrays plus a JSON metadata string, never pickled.

Every saved model (IMS generator, cyber player) is written atomically by `save_model` and read
back by `load_model`, which checks the format name and version in the metadata and turns every
way a file can be wrong (missing, truncated, not an archive, another format, bad JSON) into one
`InputError` line naming the file.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar import __version__
from mirror_avatar.atomic import write_atomic_bytes
from mirror_avatar.errors import InputError

PathLike = str | os.PathLike[str]
ZIP_MAGIC = b"PK\x03\x04"
"""The first bytes of every ``.npz`` archive (a zip file)."""


def save_model(
    path: PathLike,
    format_name: str,
    version: int,
    arrays: dict[str, NDArray[Any]],
    metadata: dict[str, Any],
) -> Path:
    """Write ``arrays`` and ``metadata`` to ``path`` atomically.

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
    np.savez(buffer, allow_pickle=False, **contents)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic_bytes(path, buffer.getvalue())
    return path


def read_archive(path: PathLike) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
    """Read any model archive: its arrays and its metadata, without checking the format.

    Raises
    ------
    InputError
        Missing file, not a readable ``.npz`` archive, or metadata that is not a JSON object.
    """
    try:
        with open(path, "rb") as file:
            if file.read(4) != ZIP_MAGIC:
                raise InputError(path, "not a readable .npz model file (not a zip archive)")
            file.seek(0)
            with np.load(file, allow_pickle=False) as archive:
                arrays = {key: archive[key] for key in archive.files}
    except InputError:
        raise
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except IsADirectoryError:
        raise InputError(path, "is a directory, not a model file") from None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as error:
        raise InputError(path, f"not a readable .npz model file ({error})") from None
    if "metadata" not in arrays:
        raise InputError(path, "not a mirror-avatar model file (no metadata)")
    try:
        metadata = json.loads(str(arrays.pop("metadata")[()]))
    except (ValueError, TypeError, IndexError):
        raise InputError(path, "metadata is not valid JSON") from None
    if not isinstance(metadata, dict):
        raise InputError(path, "metadata is not a JSON object")
    return arrays, metadata


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
        raise InputError(path, f"not a {format_name} file (format {metadata.get('format')!r})")
    if metadata.get("version") != version:
        raise InputError(path, f"unsupported {format_name} version {metadata.get('version')!r}")
    missing = sorted(set(required) - arrays.keys())
    if missing:
        raise InputError(path, f"missing array(s) {', '.join(missing)}")
    return arrays, metadata
