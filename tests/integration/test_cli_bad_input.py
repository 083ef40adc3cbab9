"""Bad input files through the real console entry point: one line on stderr, exit code 2."""

from pathlib import Path

import pytest

from console_child import run_console

SAFETY_TIMEOUT = 300
"""Seconds after which a child that still runs is killed (a hang, not a slow machine)."""

BAD_FILES = {
    "empty.csv": b"",
    "misnamed.csv": b"t,position\n0,0\n",
    "words.csv": b"time,position\n0,0\n0.01,abc\n",
    "corrupt.mat": b"MATLAB 5.0 but not really\x00\x01\x02",
    "foreign.parquet": b"\x89PNG\r\n\x1a\n\x00\x00",
    "trial.xyz": b"1,2\n",
}


@pytest.mark.parametrize("name", [*sorted(BAD_FILES), "missing.csv", "emptydir"])
def test_bad_file_is_one_line_exit_2(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    if name in BAD_FILES:
        path.write_bytes(BAD_FILES[name])
    elif name == "emptydir":
        path.mkdir()
    arguments = ["signature", str(path), "--out", str(tmp_path / "out")]
    result = run_console(arguments, tmp_path, timeout=SAFETY_TIMEOUT)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert name in lines[0]
    assert "Traceback" not in result.stderr
