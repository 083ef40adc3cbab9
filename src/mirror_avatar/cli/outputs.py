"""Output paths checked before any work: a command that cannot write its results fails first.

`check_output_dir` checks that an output folder is, or can become, a folder that files can be
written in, by writing (then removing) a probe file in it or in its nearest existing parent, so
nothing is created yet; `check_output_file` does the same for an output file, which must not be
a folder itself. Each command declares every file it will write: the files it writes in its
output folder (``files``) or beside its output file (``beside``: a learning curve, a card), and
each of them is checked the same way (not a folder, not inside a file), so that a command never
fails after its work, nor half-way through writing its results. A problem is one `InputError`
line naming the path and the option to change.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.user_files import check_path


def check_output_dir(
    path: Path, option: str = "--out", files: Iterable[str | os.PathLike[str]] = ()
) -> Path:
    """Check that the output folder ``path`` exists or can be created, and can be written in.

    Parameters
    ----------
    path
        The folder.
    option
        The option that names it, for the error line.
    files
        The files the command will write in it, relative to it (``"sub/name.csv"`` for one in
        a sub-folder); each is checked with `check_written_file`.

    Raises
    ------
    InputError
        When ``path`` or one of its parents is a file, the path cannot be a file's
        (`mirror_avatar.files.user_files.check_path`), the folder it would be made in cannot
        be written to, or a file the command will write cannot be.
    """
    check_path(path)
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
    for name in files:
        check_written_file(path / name, option)
    return path


def check_output_file(
    path: Path, suffix: str | None = None, option: str = "--out", beside: Iterable[Path] = ()
) -> Path:
    """Check that the file ``path`` can be written: its suffix, not a folder, its folder.

    ``beside`` are the other files the command writes with it (named from it: a learning curve,
    a card, a checkpoint), each checked with `check_written_file`.
    """
    check_path(path)
    if suffix is not None and path.suffix.lower() != suffix:
        raise InputError(path, f"{option} must end in {suffix}")
    if path.is_dir():
        raise InputError(path, f"is a folder; give {option} a file name")
    check_output_dir(path.parent, option)
    for other in beside:
        check_written_file(other, option)
    return path


def check_written_file(path: Path, option: str = "--out") -> Path:
    """Check that a file a command will write as part of its output is not blocked.

    A folder at ``path`` cannot be replaced by the file, and a file where one of its folders
    should be cannot hold it; either is refused, naming the path, before any work is done.
    Files already there are replaced (each atomically, when the command writes it).

    Raises
    ------
    InputError
        ``path`` is a folder, or one of its parents is a file.
    """
    check_path(path)
    if path.is_dir():
        raise InputError(
            path,
            f"is a folder where this command writes a file: move it, or choose another {option}",
        )
    blocking = next((p for p in path.parents if p.exists() and not p.is_dir()), None)
    if blocking is not None:
        raise InputError(
            path, f"cannot be written: {blocking} is a file, not a folder; choose another {option}"
        )
    return path
