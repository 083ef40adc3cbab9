"""Reading a lab export's BIDS-Motion recording back as its session: peak memory and time.

A four-player lab session (two people, two avatars) is recorded with
`mirror_avatar.sessions.writer.SessionWriter`, exported with
`mirror_avatar.lab.export.bids.export_bids`, and one participant's ``_motion.tsv`` is grown to
``--megabytes`` (default 60) of rows of eight channels, written as the export writes them (``repr``)
or, with ``--decimals N``, rounded to N decimals (short cells: more rows per megabyte, the case that
costs a row-by-row reader most). A fresh child process reads it with
`mirror_avatar.sessions.loading.load_session` and prints its time
and peak resident memory (``ru_maxrss``); a baseline child imports the package and reads the
small export. Value =
(peak - baseline peak) / file size. With ``--before SRC``, the same children run on the package
in SRC too (the source tree of the commit before a change, e.g. from ``git archive``), in the
same run. Children start through a small launcher process, so that the runner's own memory
does not count (see ``bench_reading.py``).

Usage: ``python benchmarks/bench_bids_export.py [--megabytes 60] [--decimals N] [--before SRC]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from mirror_avatar.lab.export.bids import export_bids
from mirror_avatar.sessions.graphs import ring_graph
from mirror_avatar.sessions.writer import SessionWriter

LAUNCHER = "import subprocess, sys; sys.exit(subprocess.call(sys.argv[1:]))"

READER = """
import resource, sys, time
from mirror_avatar.sessions.loading import load_session
start = time.perf_counter()
session = load_session(sys.argv[1])
print(time.perf_counter() - start, session.n_samples,
      resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""
"""Child: read a lab export's recording as its session; print seconds, samples, peak kB."""

T = 0.03
SLOTS = [
    {"label": "P1", "kind": "human", "role": "joint", "device": "pointer"},
    {"label": "A1", "kind": "avatar", "role": "joint", "spec": "ims:seed=3"},
    {"label": "P2", "kind": "human", "role": "joint", "device": "pointer"},
    {"label": "A2", "kind": "avatar", "role": "joint", "spec": "ims:seed=4"},
]


def small_export(folder: Path) -> Path:
    """Record and export a 300-sample ring session; return P1's motion file."""
    session = folder / "lab" / "s1"
    session.mkdir(parents=True)
    lab = {"session_id": "s1", "trial": 1, "condition": "group", "slots": SLOTS}
    labels, roles = [s["label"] for s in SLOTS], [s["role"] for s in SLOTS]
    writer = SessionWriter(session / "trial-01_session.csv", labels, roles, ring_graph(4), T,
                           {"lab": lab})  # fmt: skip
    rng = np.random.default_rng(0)
    for k in range(300):
        writer.append(np.concatenate([[k * T], rng.normal(0, 0.1, 16)]))
    writer.close(True, {"dropped": {}, "held": {}})
    written = export_bids(session, folder / "bids")
    return next(p for p in written if p.name.startswith("sub-P1"))


def grow(small: Path, megabytes: float, decimals: int | None, folder: Path) -> Path:
    """Copy ``small``'s recording to ``folder`` with its motion file grown to ``megabytes``."""
    stem = small.name.removesuffix("_motion.tsv")
    for suffix in ("_motion.json", "_channels.tsv"):
        (folder / f"{stem}{suffix}").write_bytes(small.with_name(f"{stem}{suffix}").read_bytes())
    target = folder / small.name
    rng = np.random.default_rng(1)
    with target.open("w", encoding="utf-8") as handle:
        while handle.tell() < megabytes * 2**20:
            block = rng.normal(0, 0.1, (10_000, 8))
            block = block if decimals is None else block.round(decimals)
            handle.write("".join("\t".join(map(repr, row)) + "\n" for row in block.tolist()))
    return target


def measure(source: str, path: Path) -> tuple[float, int, int]:
    """Run the reading child on the package in ``source``; return seconds, samples, peak kB."""
    environment = os.environ | {"PYTHONPATH": source}
    command = [sys.executable, "-c", LAUNCHER, sys.executable, "-c", READER, str(path)]
    result = subprocess.run(command, env=environment, capture_output=True, text=True, check=True)
    seconds, samples, peak = result.stdout.split()
    return float(seconds), int(samples), int(peak)


def run(quick: bool) -> list[dict]:
    """Measure reading back an export grown to 60 MB (5 MB with ``quick``), for `run.py`."""
    here = str(Path(__file__).resolve().parents[1] / "src")
    megabytes = 5.0 if quick else 60.0
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        small = small_export(folder)
        (folder / "big").mkdir()
        big = grow(small, megabytes, None, folder / "big")
        size = big.stat().st_size
        _, _, base = measure(here, small)
        seconds, samples, peak = measure(here, big)
    return [{
        "name": f"lab export's _motion.tsv read back as its session ({size / 2**20:.0f} MiB)",
        "value": round((peak - base) * 1024 / size, 2),
        "unit": "x file size",
        "baseline": f"the small export read: peak {base / 1024:.0f} MiB",
        "peak_memory_mb": round(peak / 1024, 1),
        "note": f"{samples:,} samples in {seconds:.2f} s; value = (peak - baseline peak) / size",
    }]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--megabytes", type=float, default=60.0)
    parser.add_argument("--decimals", type=int, default=None)
    parser.add_argument("--before", help="the src folder of the package before a change")
    arguments = parser.parse_args()
    here = str(Path(__file__).resolve().parents[1] / "src")
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        small = small_export(folder)
        (folder / "big").mkdir()
        big = grow(small, arguments.megabytes, arguments.decimals, folder / "big")
        size = big.stat().st_size
        print(f"file: {size / 2**20:.1f} MiB, {size:,} bytes")
        for name, source in (("now", here), ("before", arguments.before)):
            if source is None:
                continue
            _, _, base = measure(source, small)
            seconds, samples, peak = measure(source, big)
            multiple = (peak - base) * 1024 / size
            print(f"{name}: {samples:,} samples in {seconds:.2f} s, peak {peak / 1024:.0f} MiB "
                  f"(baseline {base / 1024:.0f} MiB): {multiple:.2f} x the file size")  # fmt: skip


if __name__ == "__main__":
    main()
