"""One export at a time into a BIDS dataset: a lock per folder, across threads and processes.

An export reads the dataset's tables (``participants.tsv``, each subject's ``_scans.tsv``), adds
its rows and writes them back; two exports into one folder at once would each write back the
table they read, and the rows of one would be lost. `dataset_lock` makes them take turns: a
lock per folder within the process (the lab server exports in worker threads) and an exclusive
lock on a file beside the folder across processes (``mirror-avatar lab export`` may run beside
the server), ``flock`` on POSIX, ``msvcrt.locking`` on Windows. The lock file,
``.<folder>.export-lock`` beside the dataset (not in it, so the dataset holds only BIDS files),
stays; the lock goes with the process holding it, also when it is killed.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

_LOCKS: dict[Path, threading.Lock] = {}
"""This process's lock of each dataset folder (by resolved path)."""

_GUARD = threading.Lock()
"""Guards `_LOCKS`."""


def lock_path(out_dir: Path) -> Path:
    """Return the lock file of the dataset folder ``out_dir``: ``.<name>.export-lock`` beside it."""
    return out_dir.parent / f".{out_dir.name}.export-lock"


@contextlib.contextmanager
def dataset_lock(out_dir: str | os.PathLike[str]) -> Iterator[None]:
    """Hold the dataset folder ``out_dir`` for one export: wait for any other to end first.

    Not reentrant: an export holding it must not take it again.
    """
    folder = Path(out_dir).resolve()
    with _GUARD:
        lock = _LOCKS.setdefault(folder, threading.Lock())
    with lock:
        folder.parent.mkdir(parents=True, exist_ok=True)
        descriptor = os.open(lock_path(folder), os.O_RDWR | os.O_CREAT, 0o644)
        try:
            _lock_file(descriptor)
            yield
        finally:
            os.close(descriptor)  # closing releases the file's lock


def _lock_file(descriptor: int) -> None:
    """Wait for an exclusive lock of the open file ``descriptor`` (released when it closes)."""
    if sys.platform == "win32":
        import msvcrt

        while True:  # LK_LOCK retries for 10 s, then raises: wait as long as it takes
            with contextlib.suppress(OSError):
                msvcrt.locking(descriptor, msvcrt.LK_LOCK, 1)
                return
    else:
        import fcntl

        fcntl.flock(descriptor, fcntl.LOCK_EX)
