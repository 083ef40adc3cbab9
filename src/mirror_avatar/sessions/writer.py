"""A session written as it is played: one CSV line a sample, flushed, and a sidecar kept current.

`SessionWriter` appends the CSV of `mirror_avatar.sessions.session.Session.save_csv` a sample at
a time, so a live recording is readable at every moment.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from numpy.typing import ArrayLike

from mirror_avatar.files.atomic import (
    LineFile,
    json_text,
    write_atomic_text,
)
from mirror_avatar.sessions.graphs import Graph
from mirror_avatar.sessions.session import column_names, format_row, make_sidecar


class SessionWriter:
    """Append a session to a CSV file one sample at a time, each line flushed as it is written.

    The sidecar is written when the file is opened and rewritten (atomically) by `close`, so a
    crash leaves a CSV whose complete lines `load_session` reads (a last line without its line
    end, torn, is left out with a logged warning naming the file and line), and a sidecar saying
    the recording did not finish (``metadata["complete"]`` is False until `close` says otherwise).

    Parameters
    ----------
    path
        The CSV file; it must not exist yet.
    labels, roles, graph, period, metadata
        As in `Session`.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        labels: Sequence[str],
        roles: Sequence[str],
        graph: Graph,
        period: float,
        metadata: dict[str, Any],
    ) -> None:
        self.path = Path(path)
        self.sidecar_path = self.path.with_suffix(".json")
        self.sidecar = make_sidecar(labels, roles, graph, period, dict(metadata))
        self.sidecar["metadata"]["complete"] = False
        self.n_samples = 0
        self._texts = self._written = 0
        self._writing = threading.Lock()
        self._file = LineFile(self.path, ",".join(column_names(len(labels))))
        try:
            self.annotate({})
        except OSError:
            self._file.close()
            raise

    def append(self, row: ArrayLike) -> None:
        """Write one sample: time, then each player's four channels (see `Session.table`)."""
        self._file.write(format_row(row))
        self.n_samples += 1

    def annotate(self, extra: dict[str, Any]) -> None:
        """Add ``extra`` to the sidecar's metadata now (rewritten atomically), file still open."""
        self.write_sidecar(self.sidecar_text(extra))

    def sidecar_text(self, extra: dict[str, Any]) -> tuple[int, str]:
        """Add ``extra`` to the sidecar's metadata; return its text to write, and its number.

        Call it where nothing else changes the sidecar meanwhile (under the caller's lock);
        `write_sidecar` may then write the text elsewhere, later (another thread).
        """
        self.sidecar["metadata"].update(extra)
        self._texts += 1
        return self._texts, json_text(self.sidecar)

    def write_sidecar(self, numbered: tuple[int, str]) -> None:
        """Write a text of `sidecar_text` atomically, unless a later one is on disk already."""
        number, text = numbered
        with self._writing:
            if number > self._written:
                write_atomic_text(self.sidecar_path, text)
                self._written = number

    def close(self, complete: bool, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """Close the file and rewrite the sidecar with ``complete`` and ``extra`` metadata."""
        self._file.close()
        self.sidecar["n_samples"] = self.n_samples
        self.annotate((extra or {}) | {"complete": complete})
        return self.sidecar
