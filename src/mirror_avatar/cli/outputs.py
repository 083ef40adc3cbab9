"""Output paths checked before any work: a command that cannot write its results fails first.

`check_output_dir` checks that an output folder is, or can become, a folder that files can be
written in, by writing (then removing) a probe file in it or in its nearest existing parent, so
nothing is created yet; `check_output_file` does the same for an output file, which must not be
a folder itself. A problem is one `InputError` line naming the path and the option to change.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from mirror_avatar.errors import InputError


def check_output_dir(path: Path, option: str = "--out") -> Path:
    """Check that the output folder ``path`` exists or can be created, and can be written in.

    Raises
    ------
    InputError
        When ``path`` or one of its parents is a file, or the folder it would be made in cannot
        be written to.
    """
    if path.exists() and not path.is_dir():
        raise InputError(path, f"exists and is not a folder; give {option} a folder")
    existing = next(p for p in (path, *path.absolute().parents) if p.exists())
    if not existing.is_dir():
        raise InputError(path, f"{existing} is a file, not a folder; choose another {option}")
    try:
        handle, probe = tempfile.mkstemp(dir=existing, prefix=".write-check-")
        os.close(handle)
        os.unlink(probe)
    except OSError as error:
        reason = error.strerror or type(error).__name__
        problem = f"cannot write in {existing} ({reason}); choose another {option}"
        raise InputError(path, problem) from None
    return path


def check_output_file(path: Path, suffix: str | None = None, option: str = "--out") -> Path:
    """Check that the file ``path`` can be written: its suffix, not a folder, its folder."""
    if suffix is not None and path.suffix.lower() != suffix:
        raise InputError(path, f"{option} must end in {suffix}")
    if path.is_dir():
        raise InputError(path, f"is a folder; give {option} a file name")
    check_output_dir(path.parent, option)
    return path
