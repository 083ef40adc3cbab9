"""Under a file-size limit (``ulimit -f``), a lab export fails in one line naming the file it
could not write, not the system's bare "File too large"."""

from __future__ import annotations

import resource
import subprocess
import sys

from test_lab_bids_concurrent import CLI, dyad, record

LIMIT_BYTES = 6 * 1024
"""The file-size limit of the export's process: above its small files, below its motion files."""


def limited() -> None:
    """Limit the files this process writes to `LIMIT_BYTES` (SIGXFSZ is ignored by Python)."""
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, LIMIT_BYTES))


def test_an_export_under_a_file_size_limit_names_the_file(tmp_path):
    session = record(tmp_path / "20261127T020000-001", dyad("H", trials=1))
    bids = tmp_path / "bids"
    export = subprocess.run(
        [sys.executable, "-c", CLI, "lab", "export", str(session), "--out", str(bids)],
        capture_output=True, text=True, timeout=300, preexec_fn=limited, check=False,
    )  # fmt: skip
    assert export.returncode == 2, export.stderr
    (line,) = export.stderr.splitlines()
    assert line.startswith(f"mirror-avatar: error: {bids}/") and line.endswith(": File too large")
