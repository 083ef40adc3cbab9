"""Crafted and damaged trial files through the real command line: one error line, exit code 2.

Every file is made here, in the test. Each case is a class of bad input (text that is not UTF-8,
values of the wrong type, non-finite or absurd numbers, JSON nested too deeply, files beyond the
size limits...); the command must print exactly ``mirror-avatar: error: FILE: PROBLEM`` with
values from the file cut short, and write nothing.
"""

from __future__ import annotations

import io
import json
import os
import struct
import tracemalloc
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import scipy.io

from mirror_avatar.cli import main
from mirror_avatar.common.errors import InputError
from mirror_avatar.files import trial_io
from mirror_avatar.files.importing import ECHO_CHARS
from mirror_avatar.files.trial_files import read_trial, read_trial_file

N = 200
TIMES = (np.arange(N) / 100.0).tolist()
POSITIONS = (0.2 * np.sin(np.arange(N) / 10.0)).tolist()
LONG = "1" * 4000
"""A 4000-digit value: error lines must quote only its first characters."""


def rows(cells: dict[int, str] | None = None, time: dict[int, str] | None = None) -> str:
    """``time,position`` CSV text of N samples, with some position or time cells replaced."""
    cells, time = cells or {}, time or {}
    lines = [f"{time.get(k, repr(t))},{cells.get(k, repr(x))}"
             for k, (t, x) in enumerate(zip(TIMES, POSITIONS, strict=True))]  # fmt: skip
    return "time,position\n" + "\n".join(lines) + "\n"


def csv_file(content: str | bytes) -> Callable[[Path], tuple[Path, Path]]:
    def make(folder: Path) -> tuple[Path, Path]:
        path = folder / "trial.csv"
        path.write_bytes(content.encode() if isinstance(content, str) else content)
        return path, path

    return make


def parquet_file(
    metadata: str | bytes | None = None, columns: dict[str, pa.Array] | None = None
) -> Callable[[Path], tuple[Path, Path]]:
    def make(folder: Path) -> tuple[Path, Path]:
        path = folder / "trial.parquet"
        table = pa.table(columns or {"time": TIMES, "position": POSITIONS})
        if metadata is not None:
            table = table.replace_schema_metadata({"mirror_avatar": metadata})
        pq.write_table(table, path)
        return path, path

    return make


def mat_file(x: object, compress: bool = False) -> Callable[[Path], tuple[Path, Path]]:
    def make(folder: Path) -> tuple[Path, Path]:
        path = folder / "trial.mat"
        struct = np.empty((1, 1), dtype=[("x", object)])
        struct[0, 0] = (x,)
        scipy.io.savemat(path, {"s": struct}, do_compression=compress)
        return path, path

    return make


def bids_file(
    sidecar: str | bytes | None = '{"SamplingFrequency": 100}',
    motion: str | bytes | None = None,
    channels: str | None = None,
    named: str = "motion",
) -> Callable[[Path], tuple[Path, Path]]:
    """A BIDS-Motion trial; ``named``: the file the error must name (motion, sidecar, channels)."""

    def make(folder: Path) -> tuple[Path, Path]:
        stem = folder / "sub-01_task-mirror"
        paths = {"motion": Path(f"{stem}_motion.tsv"), "sidecar": Path(f"{stem}_motion.json"),
                 "channels": Path(f"{stem}_channels.tsv")}  # fmt: skip
        text = "\n".join(map(repr, POSITIONS)) + "\n" if motion is None else motion
        for kind, content in (("motion", text), ("sidecar", sidecar), ("channels", channels)):
            if content is not None:
                data = content.encode() if isinstance(content, str) else content
                paths[kind].write_bytes(data)
        return paths["motion"], paths[named]

    return make


def parquet_truncated(folder: Path) -> tuple[Path, Path]:
    path, _ = parquet_file()(folder)
    path.write_bytes(path.read_bytes()[:-30])
    return path, path


def mat_two_variables(folder: Path) -> tuple[Path, Path]:
    path = folder / "trial.mat"
    scipy.io.savemat(path, {"v" + "a" * 60: np.ones(3), "w": np.ones(3)})
    return path, path


def folder_of_bad_files(folder: Path) -> tuple[Path, Path]:
    inside = folder / "P01"
    inside.mkdir()
    (inside / "a.csv").write_bytes(b"\xff\xfe junk")
    (inside / "b.parquet").write_bytes(b"PAR1 not really")
    return inside, inside


def struct_cell() -> np.ndarray:
    cell = np.empty((2, 1), dtype=object)
    cell[0, 0], cell[1, 0] = np.ones(3), np.ones(4)
    return cell


DEEP = "[" * 100_000 + "]" * 100_000
CASES: dict[str, tuple[Callable[[Path], tuple[Path, Path]], str]] = {
    # CSV: empty, binary, not UTF-8, unparseable, non-numeric, non-finite, non-increasing
    "csv empty": (csv_file(""), "empty file"),
    "csv blank lines": (csv_file("\n  \n\n"), "empty file"),
    "csv header only": (csv_file("time,position\n"), "only 0 samples"),
    "csv binary junk": (csv_file(bytes(range(256)) * 8), "not UTF-8"),
    "csv latin-1": (csv_file("time,position\n0,é\n".encode("latin-1")), "not UTF-8"),
    "csv unclosed quote": (csv_file('time,position\n0,"0.1\n' + rows()), "not a valid CSV"),
    "csv missing column": (csv_file(rows().replace("time,", "t,", 1)), "missing column(s)"),
    "csv word": (csv_file(rows({5: "abc"})), "row 7: 'abc' in column 'position'"),
    "csv nul byte": (csv_file(rows({5: "0.\x001"})), "row 7: '0.\\x001'"),
    "csv 4000 digits": (csv_file(rows({5: LONG + "x"})), "(4001 characters)"),
    "csv field over 128 KB": (csv_file(rows({5: "x" * 200_000})), "(200000 characters)"),
    "csv 4000-digit number": (csv_file(rows({5: LONG})), "position is inf"),
    "csv missing time": (csv_file(rows(time={5: ""})), "row 7: time is missing"),
    "csv nan time": (csv_file(rows(time={5: "nan"})), "row 7: time is missing"),
    "csv inf time": (csv_file(rows(time={5: "inf"})), "row 7: time is inf"),
    "csv inf position": (csv_file(rows({5: "-inf"})), "position is -inf"),
    "csv repeated time": (csv_file(rows(time={5: "0.04"})), "time does not increase"),
    "csv absurd time": (csv_file(rows(time={5: "1e308", 6: "-1e308"})), "does not increase"),
    # Parquet: metadata of the wrong shape or type, columns that are no numbers, damage
    "parquet empty file": (lambda f: _rename(csv_file(b"")(f), ".parquet"), "Parquet"),
    "parquet not parquet": (lambda f: _rename(csv_file(b"\x89PNG\r\n")(f), ".parquet"), "Parquet"),
    "parquet truncated": (parquet_truncated, "not a readable Parquet file"),
    "parquet metadata list": (parquet_file("[1, 2]"), "is a list, not a JSON object"),
    "parquet metadata deep": (parquet_file(DEEP), "nested deeper than the limit of 32"),
    "parquet metadata not json": (parquet_file("{label"), "is not valid JSON"),
    "parquet metadata binary": (parquet_file(b"\xff\xfe\x00"), "not UTF-8"),
    "parquet metadata of a list": (parquet_file('{"metadata": [1]}'), "metadata is a list"),
    "parquet label object": (parquet_file('{"label": {"a": 1}}'), "label is an object"),
    "parquet label long": (parquet_file(json.dumps({"label": LONG})), "(4000 characters)"),
    "parquet group dot-dot": (parquet_file('{"group": ".."}'), "group '..' is not a usable name"),
    "parquet text column": (
        parquet_file(columns={"time": [str(t) for t in TIMES], "position": POSITIONS}),
        "column 'time' holds string",
    ),
    "parquet list column": (
        parquet_file(columns={"time": TIMES, "position": [[x] for x in POSITIONS]}),
        "column 'position' holds list",
    ),
    "parquet missing column": (parquet_file(columns={"t": TIMES}), "missing column(s)"),
    # MATLAB: fields of the wrong type or shape, damage, many names
    "mat text x": (mat_file("hello there"), "holds text"),
    "mat complex x": (mat_file(np.ones(N) * (1 + 1j)), "holds complex numbers"),
    "mat cell x": (mat_file(struct_cell()), "holds a cell array"),
    "mat matrix x": (mat_file(np.ones((N, 3))), "200x3 array, not a vector"),
    "mat nan x": (mat_file(np.full(N, np.nan)), "position is nan"),
    "mat junk": (lambda f: _rename(csv_file(b"MATLAB 5.0 \x00\x01")(f), ".mat"), "MATLAB"),
    "mat two long names": (mat_two_variables, "(61 characters)"),
    # BIDS-Motion: sidecar values of every wrong kind, channels, motion text
    "bids no sidecar": (bids_file(sidecar=None), "no sidecar"),
    "bids 400 digits": (
        bids_file('{"SamplingFrequency": ' + "1" * 400 + "}", named="sidecar"),
        "the number 11111111111111111111... is beyond the range of float64",
    ),
    "bids 5000 digits": (
        bids_file('{"SamplingFrequency": ' + "1" * 5000 + "}", named="sidecar"),
        "the number 11111111111111111111... is beyond the range of float64",
    ),
    "bids rate text": (bids_file('{"SamplingFrequency": "100"}', named="sidecar"), "is text"),
    "bids rate bool": (bids_file('{"SamplingFrequency": true}', named="sidecar"), "true or"),
    "bids rate list": (bids_file('{"SamplingFrequency": [100]}', named="sidecar"), "a list"),
    "bids rate nan": (
        bids_file('{"SamplingFrequency": NaN}', named="sidecar"),
        "NaN is not a JSON number",
    ),
    "bids rate inf": (
        bids_file('{"SamplingFrequency": Infinity}', named="sidecar"),
        "Infinity is not a JSON number",
    ),
    "bids rate zero": (bids_file('{"SamplingFrequency": 0}', named="sidecar"), "0 Hz is"),
    "bids rate huge": (bids_file('{"SamplingFrequency": 1e300}', named="sidecar"), "1e+300"),
    "bids no rate": (bids_file('{"TaskName": "mirror"}', named="sidecar"), "no Sampling"),
    "bids sidecar list": (bids_file("[100]", named="sidecar"), "a list, not a JSON object"),
    "bids sidecar deep": (bids_file(DEEP, named="sidecar"), "nested deeper than the limit of 32"),
    "bids sidecar binary": (bids_file(b"\xff\xfe\x00\x01", named="sidecar"), "not UTF-8"),
    "bids task name object": (
        bids_file('{"SamplingFrequency": 100, "TaskName": {}}', named="sidecar"),
        "TaskName is an object",
    ),
    "bids channels unit": (
        bids_file(channels=f"name\ttype\tunits\nx\tPOS\t{LONG}\n", named="channels"),
        "(4000 characters) of channel 'x'",
    ),
    "bids channel beyond the columns": (
        bids_file(channels="name\ttype\tunits\na\tMISC\tmm\nb\tPOS\tmm\n", named="channels"),
        "2 channels, but the first row",
    ),
    "bids channels unnamed": (
        bids_file(motion="0\t0\n" * N, channels=f"name\ttype\n{LONG}\tMISC\ny\tMISC\n"),
        "2 channels (1111",
    ),
    "bids motion empty": (bids_file(motion=""), "empty file"),
    "bids motion binary": (bids_file(motion=bytes(range(256))), "not UTF-8"),
    "bids motion word": (bids_file(motion="0.1\n" * 10 + "w" * 5000 + "\n"), "row 11: 'www"),
    # a folder of nothing but bad files
    "folder of bad files": (folder_of_bad_files, "no readable trial file in it (2 skipped)"),
}


def _rename(made: tuple[Path, Path], suffix: str) -> tuple[Path, Path]:
    target = made[0].with_suffix(suffix)
    made[0].rename(target)
    return target, target


COMMANDS = {
    "signature": lambda path, out: ["signature", str(path), "--out", str(out)],
    "generator fit": lambda path, out: ["generator", "fit", str(path), "--out", str(out)],
}


def run_refused(capsys, arguments: list[str], named: Path, problem: str) -> str:
    """Run the command line; check it refused the input in one line naming ``named``."""
    status = main(arguments)
    error = capsys.readouterr().err
    assert status == 2, error
    assert error.count("\n") == 1 and error.endswith("\n"), error
    assert error.startswith(f"mirror-avatar: error: {named}"), error
    assert problem in error, error
    assert len(error) < len(str(named)) + 250, "a value from the file was echoed in full"
    return error


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("case", sorted(CASES))
def test_a_bad_file_is_one_line_and_nothing_is_written(tmp_path, capsys, case, command) -> None:
    folder = tmp_path / "data"
    folder.mkdir()
    make, problem = CASES[case]
    path, named = make(folder)
    out = tmp_path / ("model.npz" if command == "generator fit" else "out")
    run_refused(capsys, COMMANDS[command](path, out), named, problem)
    assert not out.exists()


@pytest.mark.parametrize(
    "arguments",
    [
        ["convert", "{path}", "--out", "{out}"],
        ["reproduce", "--quick", "--data", "{path}", "--out", "{out}"],
    ],  # fmt: skip
    ids=["convert", "reproduce"],
)
@pytest.mark.parametrize("case", ["csv field over 128 KB", "parquet metadata deep", "mat text x",
                                  "bids 400 digits"])  # fmt: skip
def test_the_other_reading_commands_refuse_in_one_line(tmp_path, capsys, arguments, case) -> None:
    folder = tmp_path / "data"
    folder.mkdir()
    make, problem = CASES[case]
    path, named = make(folder)
    out = tmp_path / "out"
    filled = [a.format(path=path, out=out) for a in arguments]
    run_refused(capsys, filled, named, problem)
    assert not out.exists()


SPARSE_FILES = {
    "trial.csv": b"time,position\n0,0\n",
    "trial.parquet": b"PAR1",
    "trial.mat": b"MATLAB 5.0 MAT-file",
    "sub-01_task-mirror_motion.tsv": b"0\n",
}


@pytest.mark.parametrize("name", sorted(SPARSE_FILES))
def test_a_file_over_the_size_cap_is_refused_before_reading(tmp_path, capsys, name) -> None:
    """A sparse file just over `MAX_FILE_BYTES` (no gigabyte is written) is refused by its size."""
    path = tmp_path / name
    with path.open("wb") as handle:
        handle.write(SPARSE_FILES[name])
        handle.truncate(trial_io.MAX_FILE_BYTES + 1)
    path.with_name("sub-01_task-mirror_motion.json").write_text('{"SamplingFrequency": 100}')
    out = tmp_path / "out"
    error = run_refused(capsys, COMMANDS["signature"](path, out), path, "over the limit")
    assert f"{trial_io.MAX_FILE_BYTES + 1:,} bytes" in error
    assert f"{trial_io.MAX_FILE_BYTES:,} bytes (1024 MiB)" in error
    assert not out.exists()


def test_a_sidecar_over_its_cap_is_refused(tmp_path, capsys) -> None:
    path, _ = bids_file()(tmp_path)
    sidecar = path.with_name("sub-01_task-mirror_motion.json")
    with sidecar.open("r+b") as handle:
        handle.truncate(trial_io.MAX_SIDECAR_BYTES + 1)
    run_refused(capsys, COMMANDS["signature"](path, tmp_path / "o"), sidecar, "(16 MiB)")


@pytest.mark.parametrize(
    ("make", "problem"),
    [
        (csv_file(rows()), f"more than {N // 2:,} rows"),
        (parquet_file(), f"{N:,} rows, over the limit of {N // 2:,}"),
        (bids_file(), f"more than {N // 2:,} rows"),
    ],
    ids=["csv", "parquet", "bids"],
)
def test_more_rows_than_the_limit_are_refused(tmp_path, capsys, monkeypatch, make, problem):
    """Huge line counts: reading stops one row past `MAX_SAMPLES` (made small here)."""
    monkeypatch.setattr(trial_io, "MAX_SAMPLES", N // 2)
    path, named = make(tmp_path)
    run_refused(capsys, COMMANDS["generator fit"](path, tmp_path / "m.npz"), named, problem)


def test_a_compressed_mat_that_inflates_past_the_cap_is_refused(tmp_path, capsys, monkeypatch):
    """A MATLAB file whose compressed variables inflate beyond `MAX_FILE_BYTES` (made small)."""
    path, _ = mat_file(np.zeros(200_000), compress=True)(tmp_path)
    monkeypatch.setattr(trial_io, "MAX_FILE_BYTES", 100_000)
    assert path.stat().st_size < trial_io.MAX_FILE_BYTES
    run_refused(capsys, COMMANDS["signature"](path, tmp_path / "o"), path, "inflate to over")


def test_awkward_but_valid_files_are_still_read(tmp_path) -> None:
    """Siblings of the hostile cases that are fine: they must keep reading."""
    text = rows({5: " NA ", 6: "Nan"}).replace("time,position\n", "\ufefftime,position,note\n")
    lines = text.splitlines()
    lines[10] += "," + "n" * 200_000
    (tmp_path / "a.csv").write_text("\n".join(lines[:50]) + "\n\n,,\n" + "\n".join(lines[50:]))
    trial = read_trial(tmp_path / "a.csv")
    assert trial.n_samples == N and trial.metadata["import"]["interpolated_samples"] == 2
    path, _ = mat_file(np.asarray(POSITIONS)[:, None], compress=True)(tmp_path)
    np.testing.assert_allclose(read_trial(path).positions, POSITIONS)


def test_reading_a_csv_takes_memory_near_its_size(tmp_path) -> None:
    """Numbers go straight into arrays: no Python object per cell (the old reader took 13x)."""
    n = 100_000
    times, positions = np.arange(n) / 100.0, 0.2 * np.sin(np.arange(n) / 50.0)
    text = "".join(
        f"{t!r},{x!r}\n" for t, x in zip(times.tolist(), positions.tolist(), strict=True)
    )
    path = tmp_path / "big.csv"
    path.write_text("time,position\n" + text)
    read_trial(path)
    tracemalloc.start()
    try:
        read_trial(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 3 * path.stat().st_size


def test_echoed_values_are_cut() -> None:
    from mirror_avatar.files.importing import excerpt

    assert excerpt("abc") == "'abc'" and excerpt(12.5) == "12.5"
    assert excerpt(LONG) == "'" + "1" * ECHO_CHARS + "'... (4000 characters)"
    assert excerpt("a\nb", quote=False) == "a\\nb"


def _read_in_children(paths: list[Path]) -> dict[Path, str]:
    """Read MATLAB trial files in forked children; say how each read that was neither fine nor
    refused ended.

    One child reads the files in turn, reporting each read on a pipe, until one kills it or
    raises something other than `InputError`; the next child goes on after that file.
    """
    problems: dict[Path, str] = {}
    start = 0
    while start < len(paths):
        reading, writing = os.pipe()
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the child
            os.close(reading)
            for path in paths[start:]:
                try:
                    read_trial_file(path)
                except InputError:
                    pass
                except BaseException:
                    os._exit(3)
                os.write(writing, b".")
            os._exit(0)
        os.close(writing)
        with os.fdopen(reading, "rb") as reports:
            stopped = start + len(reports.read())
        status = os.waitpid(pid, 0)[1]
        if stopped < len(paths):
            problems[paths[stopped]] = (
                f"killed by signal {os.WTERMSIG(status)}"
                if os.WIFSIGNALED(status)
                else "raised something other than InputError"
            )
        start = stopped + 1
    return problems


@pytest.mark.parametrize("compress", [False, True], ids=["plain", "compressed"])
def test_a_damaged_mat_is_refused_and_never_crashes(tmp_path, compress) -> None:
    """Every 4-byte word of a struct-and-cell file overwritten with codes SciPy trusts (data
    types and array classes it would read the wrong way): refused or read, never a crash."""
    cell = np.empty((1, 2), dtype=object)
    cell[0, 0], cell[0, 1] = np.arange(3.0), "ab"
    buffer = io.BytesIO()
    scipy.io.savemat(buffer, {"s": {"x": np.arange(5.0)}, "c": cell})
    plain = buffer.getvalue()
    damages = {}
    for position in range(128, len(plain), 4):
        for value in (0, 8, 99, 0xFFFF0000, 0x7FFFFFFF):
            damaged = bytearray(plain)
            struct.pack_into("<I", damaged, position, value)
            if compress:
                damaged = bytearray(_compressed_variables(bytes(damaged)))
            path = tmp_path / f"damaged-{position}-{value:x}.mat"
            path.write_bytes(damaged)
            damages[path] = f"word at {position} = {value:#x}"
    problems = _read_in_children(list(damages))
    assert not problems, [f"{damages[path]}: {how}" for path, how in problems.items()][:5]


def _compressed_variables(plain: bytes) -> bytes:
    """The same MATLAB v5 file with each top-level variable zlib-compressed (miCOMPRESSED)."""
    parts, position = [plain[:128]], 128
    while position + 8 <= len(plain):
        length = min(struct.unpack_from("<I", plain, position + 4)[0], len(plain) - position - 8)
        packed = zlib.compress(plain[position : position + 8 + length])
        parts.append(struct.pack("<II", 15, len(packed)) + packed)
        position += 8 + length
    return b"".join(parts)
