"""Reading trial files: peak memory as a multiple of the file's size, and the size cap.

- Memory multiple, per format (CSV, BIDS-Motion TSV, Parquet, MATLAB): a 100 Hz trial of
  ``0.2 sin(t)`` is written in chunks (CSV and TSV of about 256 MB, 8 MB with ``--quick``;
  Parquet and MATLAB with as many samples as the CSV, the MATLAB file as a struct array of
  trials of at most `MAT_TRIAL_SAMPLES` samples). A fresh child process reads it with
  `read_trial_file` and prints its peak resident memory (``ru_maxrss``); a baseline child
  imports the readers and reads a tiny file of the same format (import and library cost).
  Value = (peak - baseline peak) / file size. For CSV, baseline column = the same multiple,
  measured in the same run, for the previous reader's way: Python's ``csv`` module reading all
  rows into a list of lists, converted to a float array (its child imports the readers too,
  and the CSV baseline child is subtracted); ratio = ours / that.
- Size cap: a sparse CSV file one byte over `MAX_FILE_BYTES` given to ``mirror-avatar
  signature``; value = the command's wall time (interpreter start and imports included),
  baseline = the same command given a missing file, and its exit code and error line in the
  note.

Children are started through a small launcher process: Linux counts into a child's
``ru_maxrss`` the peak memory of the process that started it (here the benchmark runner, which
may hold hundreds of MB after other benchmarks), not only the child's own. Children run one
at a time; with ``--quick``, two at a time (times of 8 MB reads mean little, and each child
spends about two seconds importing).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, ThreadPoolExecutor
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from numpy.typing import NDArray

from mirror_avatar.files.bids.writing import write_bids_motion
from mirror_avatar.files.trial_io import (
    MAX_FILE_BYTES,
    write_csv_trial,
    write_mat_struct,
    write_parquet_trial,
)
from mirror_avatar.files.trials import make_trial

Array = NDArray[np.float64]
RATE = 100.0
TEXT_CHUNK_ROWS = 2**16
PARQUET_CHUNK_ROWS = 2**20
TINY_SAMPLES = 1000
MB = 2**20

LAUNCHER = "import subprocess, sys; sys.exit(subprocess.call(sys.argv[1:]))"
"""Starts the measured child, so that its ``ru_maxrss`` does not include the runner's memory."""

READER = """
import resource, sys, time
from mirror_avatar.files.trial_files import read_trial_file
start = time.perf_counter()
trials = read_trial_file(sys.argv[1])
seconds = time.perf_counter() - start
samples = sum(trial.times.size for trial in trials)
print(seconds, samples, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""
"""Child: read a trial file; print seconds, samples and peak resident memory (kB)."""

REFERENCE = """
import csv, resource, sys, time
import numpy as np
import mirror_avatar.files.trial_io
start = time.perf_counter()
with open(sys.argv[1], newline="", encoding="utf-8") as handle:
    rows = list(csv.reader(handle))
values = np.array(rows[1:], dtype=np.float64)
seconds = time.perf_counter() - start
print(seconds, len(values), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""
"""Child: the previous CSV reader's way (``csv`` rows in a list, then a float array)."""

MAT_TRIAL_SAMPLES = 2**19
"""Most samples in one element of a MATLAB struct array: the reader spreads each element's
samples over `mirror_avatar.files.trial_files.MAT_DURATION` (60 s), and a trial's rate is at most
10 kHz."""

MAT_WRITER = """
import math, sys
import numpy as np, scipy.io
samples, most = int(sys.argv[2]), int(sys.argv[3])
x = 0.2 * np.sin(np.arange(samples) / 100.0)
parts = np.array_split(x, math.ceil(samples / most))
struct = np.empty((1, len(parts)), dtype=[("x", object)])
for k, part in enumerate(parts):
    struct[0, k] = (part[:, None],)
scipy.io.savemat(sys.argv[1], {"trial": struct})
"""
"""Child: write a MATLAB 1xK struct array with one field ``x``, positions split in K trials."""

CLI = """
import atexit, resource
atexit.register(lambda: print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss))
from mirror_avatar.console import run
run()
"""
"""Child: the command line, printing its peak resident memory (kB) on exit."""


class Reading(NamedTuple):
    """What a reading child printed."""

    seconds: float
    samples: int
    peak_kb: int


class Command(NamedTuple):
    """How a command-line child ended."""

    exit_code: int
    error: str
    seconds: float
    peak_kb: int


def launch(code: str, *args: str) -> list[str]:
    """Command running Python ``code`` with ``args`` in a child of a small launcher process."""
    return [sys.executable, "-c", LAUNCHER, sys.executable, "-c", code, *args]


def chunks(rows: int) -> Iterator[tuple[Array, Array]]:
    """Yield times (s) and positions of an endless 100 Hz trial, ``rows`` samples at a time."""
    first = 0
    while True:
        times = np.arange(first, first + rows) / RATE
        yield times, 0.2 * np.sin(times)
        first += rows


def csv_lines(times: Array, positions: Array) -> str:
    """CSV rows ``time,position`` as `write_csv_trial` writes them."""
    pairs = zip(times.tolist(), positions.tolist(), strict=True)
    return "".join(f"{t!r},{x!r}\n" for t, x in pairs)


def tsv_lines(times: Array, positions: Array) -> str:
    """BIDS-Motion rows (one position each) as `write_bids_motion` writes them."""
    return "".join(f"{x!r}\n" for x in positions.tolist())


def write_text(path: Path, header: str, lines: Callable[[Array, Array], str], size: int) -> int:
    """Write a text trial of at least ``size`` bytes in chunks; return its number of samples."""
    written, samples = len(header), 0
    with path.open("w", encoding="utf-8") as handle:
        handle.write(header)
        for times, positions in chunks(TEXT_CHUNK_ROWS):
            if written >= size:
                break
            text = lines(times, positions)
            handle.write(text)
            written += len(text)
            samples += times.size
    return samples


def write_big_csv(path: Path, size: int) -> int:
    """Write a CSV trial of about ``size`` bytes; return its number of samples."""
    return write_text(path, "time,position\n", csv_lines, size)


def write_big_tsv(path: Path, size: int) -> int:
    """Write a BIDS-Motion trial of about ``size`` bytes with its sidecar; return its samples."""
    sidecar = path.with_name(path.name.removesuffix(".tsv") + ".json")
    sidecar.write_text(json.dumps({"SamplingFrequency": RATE}))
    return write_text(path, "", tsv_lines, size)


def write_big_parquet(path: Path, samples: int) -> None:
    """Write a Parquet trial of ``samples`` samples, a row group at a time."""
    schema = pa.schema([("time", pa.float64()), ("position", pa.float64())])
    with pq.ParquetWriter(path, schema) as writer:
        for first, (times, positions) in zip(
            range(0, samples, PARQUET_CHUNK_ROWS), chunks(PARQUET_CHUNK_ROWS), strict=False
        ):
            keep = min(PARQUET_CHUNK_ROWS, samples - first)
            table = pa.table({"time": times[:keep], "position": positions[:keep]}, schema=schema)
            writer.write_table(table)


def write_big_mat(path: Path, samples: int) -> None:
    """Write ``samples`` positions as MATLAB trials, in a child process (kept out of this one)."""
    command = [sys.executable, "-c", MAT_WRITER, str(path), str(samples), str(MAT_TRIAL_SAMPLES)]
    subprocess.run(command, check=True)


def write_tiny(folder: Path) -> dict[str, Path]:
    """Write a tiny trial in each format with the package's writers; return the paths by format."""
    times = np.arange(TINY_SAMPLES) / RATE
    trial = make_trial(times, 0.2 * np.sin(times), source="bench", label="tiny")
    paths = {
        "CSV": folder / "tiny.csv",
        "BIDS TSV": folder / "sub-tiny_motion.tsv",
        "Parquet": folder / "tiny.parquet",
        "MATLAB": folder / "tiny.mat",
    }
    write_csv_trial(trial, paths["CSV"])
    write_bids_motion(trial, paths["BIDS TSV"])
    write_parquet_trial(trial, paths["Parquet"])
    write_mat_struct([trial], paths["MATLAB"], "trial")
    return paths


def measure(code: str, path: Path) -> Reading:
    """Run a reading child (`READER` or `REFERENCE`) on ``path`` and parse what it prints."""
    result = subprocess.run(launch(code, str(path)), capture_output=True, text=True, check=False)
    if result.returncode != 0:
        raise RuntimeError(f"reading {path.name} failed: {result.stderr.strip()[-500:]}")
    seconds, samples, peak = result.stdout.split()
    return Reading(float(seconds), int(samples), int(peak))


def multiple(big: Reading, baseline: Reading, size: int) -> float:
    """Memory a read adds over the baseline child, as a multiple of the file's ``size``."""
    return (big.peak_kb - baseline.peak_kb) * 1024 / size


def format_row(label: str, path: Path, samples: int, baseline: Reading, big: Reading) -> dict:
    """Describe reading ``path`` (``samples`` samples) against its ``baseline`` child."""
    size = path.stat().st_size
    if big.samples != samples:
        raise RuntimeError(f"{path.name}: read {big.samples:,} samples of {samples:,}")
    return {
        "name": f"peak memory reading {label}",
        "value": round(multiple(big, baseline, size), 2),
        "unit": "x file size",
        "peak_memory_mb": round(big.peak_kb / 1024, 1),
        "note": (
            f"{size / MB:.1f} MB file, {samples:,} samples, read in {big.seconds:.2f} s "
            f"({size / MB / big.seconds:.0f} MB/s); baseline child (imports, tiny file) "
            f"{baseline.peak_kb / 1024:.0f} MB"
        ),
    }


def with_reference(row: dict, size: int, baseline: Reading, reference: Reading) -> dict:
    """Add to the CSV row the multiple of the ``csv``-module reader on the same file."""
    value = multiple(reference, baseline, size)
    return {
        **row,
        "baseline": round(value, 2),
        "ratio": round(row["value"] / value, 3),
        "note": (
            f"{row['note']}; baseline = csv module rows to a float array: read in "
            f"{reference.seconds:.2f} s, peak {reference.peak_kb / 1024:.0f} MB"
        ),
    }


def format_rows(
    pool: Executor, tiny: dict[str, Path], big: dict[str, tuple[Path, int]]
) -> list[dict]:
    """Run the reading children in ``pool`` and make a row per format."""
    labels = list(big)
    jobs = [(READER, tiny[label]) for label in labels]
    jobs += [(READER, big[label][0]) for label in labels]
    jobs += [(REFERENCE, big["CSV"][0])]
    readings = list(pool.map(lambda job: measure(*job), jobs))
    count = len(labels)
    baselines, bigs, reference = readings[:count], readings[count:-1], readings[-1]
    rows = [
        format_row(label, *big[label], baseline, reading)
        for label, baseline, reading in zip(labels, baselines, bigs, strict=True)
    ]
    size = big["CSV"][0].stat().st_size
    rows[0] = with_reference(rows[0], size, baselines[0], reference)
    return rows


def run_cli(*args: str) -> Command:
    """Run ``mirror-avatar`` with ``args``; return its exit code, error line, time and peak."""
    start = time.perf_counter()
    result = subprocess.run(launch(CLI, *args), capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - start
    lines = result.stdout.split()
    return Command(result.returncode, result.stderr.strip(), seconds, int(lines[-1]))


def shorten(error: str, folder: Path) -> str:
    """Return the error output without the temporary folder, cut to at most 140 characters."""
    text = " / ".join(error.splitlines()).replace(f"{folder}/", "")
    return text if len(text) <= 140 else text[:137] + "..."


def over_cap_row(pool: Executor, folder: Path) -> dict:
    """Time ``mirror-avatar signature`` refusing a sparse CSV one byte over the cap."""
    path = folder / "over_cap.csv"
    with path.open("w") as handle:
        handle.write("time,position\n")
        handle.truncate(MAX_FILE_BYTES + 1)
    commands = [(str(path),), (str(folder / "missing.csv"),)]
    refused, missing = pool.map(
        lambda given: run_cli("signature", *given, "--out", str(folder / "out")), commands
    )
    lines = len(refused.error.splitlines())
    return {
        "name": "file over the size cap refused (signature)",
        "value": round(refused.seconds, 3),
        "unit": "s",
        "baseline": round(missing.seconds, 3),
        "ratio": round(refused.seconds / missing.seconds, 3),
        "peak_memory_mb": round(refused.peak_kb / 1024, 1),
        "note": (
            f"exit code {refused.exit_code} (expected 2), {lines} error line(s): "
            f"{shorten(refused.error, folder)}; baseline = the same command given a missing "
            f"file (exit {missing.exit_code}, peak {missing.peak_kb / 1024:.0f} MB); times "
            "include interpreter start and imports"
        ),
    }


def write_big(folder: Path, size: int) -> dict[str, tuple[Path, int]]:
    """Write the big trial of each format; return its path and number of samples by format."""
    csv_path, tsv_path = folder / "big.csv", folder / "sub-big_motion.tsv"
    samples = write_big_csv(csv_path, size)
    big = {"CSV": (csv_path, samples), "BIDS TSV": (tsv_path, write_big_tsv(tsv_path, size))}
    big["Parquet"] = (folder / "big.parquet", samples)
    big["MATLAB"] = (folder / "big.mat", samples)
    write_big_parquet(big["Parquet"][0], samples)
    write_big_mat(big["MATLAB"][0], samples)
    return big


def run(quick: bool) -> list[dict]:
    size = (8 if quick else 256) * MB
    with (
        tempfile.TemporaryDirectory(prefix="bench_reading_", dir="/tmp") as name,
        ThreadPoolExecutor(2 if quick else 1) as pool,
    ):
        folder = Path(name)
        rows = format_rows(pool, write_tiny(folder), write_big(folder, size))
        rows.append(over_cap_row(pool, folder))
    return rows
