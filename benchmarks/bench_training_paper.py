"""Paper-scale training, ``mirror-avatar train --sessions 24000``, beside commit `BASELINE_COMMIT`.

Each run is a child process that imports the package from one tree, trains once on a few short
sessions (so numba compiles, or loads its cache, before the clock starts), then times
`train_cyber_player` as ``mirror-avatar train`` calls it: follower, target VT5, partners
VT1..VT4, seed 0, 60 s sessions, 2 local workers (threads here; processes in the baseline). The
baseline's tree is a git worktree of `BASELINE_COMMIT` at `BASELINE_TREE`, made if missing (a
clone without that commit, a shallow one, skips the baseline and says so). The runs alternate,
baseline then this tree, for ``rounds`` rounds, so both see the same load; each round's ratio is
baseline seconds over this tree's. Peak memory is each child's peak resident size (``wait4``);
the baseline's two worker processes are not counted (on Linux they inherit the parent's peak).
The machine's 1-minute load average is sampled every `LOAD_EVERY` seconds during each run.

``python benchmarks/bench_training_paper.py`` prints a table of every run (``--sessions``,
``--rounds``, ``--quick``: 2400 sessions; ``--out FILE`` also writes it); ``benchmarks/run.py
training_paper`` writes the rows into ``results.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

BASELINE_COMMIT = "c9581d4"
"""The engine the issue measures against (98 s for the paper's 24 000 sessions)."""

ROOT = Path(__file__).parents[1]
BASELINE_TREE = Path("/tmp") / BASELINE_COMMIT
PAPER_SESSIONS = 24_000
QUICK_SESSIONS = 2_400
LOAD_EVERY = 5.0
"""Seconds between the samples of the 1-minute load average taken while a child runs."""
TARGET_SECONDS = 20.0
"""The issue's target for the paper's sessions on two idle cores."""

CHILD = """
import hashlib, json, sys, time
from mirror_avatar.datasets import load_zhai2017
try:
    from mirror_avatar.training.cast import SEEN_PARTNERS, TARGET, make_virtual_trainers
    from mirror_avatar.training.imitation import train_cyber_player
except ImportError:  # the baseline: training was one module
    from mirror_avatar.training import (
        SEEN_PARTNERS, TARGET, make_virtual_trainers, train_cyber_player)

n_sessions = int(sys.argv[1])
trainers = make_virtual_trainers(load_zhai2017())
target = trainers[TARGET].generator
partners = [trainers[i].generator for i in SEEN_PARTNERS]
train_cyber_player(target, partners, n_sessions=8, duration=5.0, progress=False)
began = time.perf_counter()
player, curve = train_cyber_player(target, partners, n_sessions=n_sessions, seed=0, progress=False)
seconds = time.perf_counter() - began
q = getattr(player, "q_table_", None)
print(json.dumps({
    "seconds": seconds,
    "final_rms": curve.rms[-1],
    "q_sha256": hashlib.sha256(q.tobytes()).hexdigest()[:12] if q is not None else "",
}))
"""


def machine() -> str:
    """Describe the machine and its load average now."""
    load = os.getloadavg()
    return (
        f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"load average {load[0]:.2f}/{load[1]:.2f}/{load[2]:.2f}"
    )


def baseline_tree() -> Path | None:
    """Return the baseline's ``src``, its worktree made if missing; None without the commit."""
    found = subprocess.run(
        ["git", "cat-file", "-e", f"{BASELINE_COMMIT}^{{commit}}"], cwd=ROOT, capture_output=True
    )
    if found.returncode != 0:
        return None
    if not (BASELINE_TREE / "src" / "mirror_avatar").is_dir():
        subprocess.run(
            ["git", "worktree", "add", "--detach", str(BASELINE_TREE), BASELINE_COMMIT],
            cwd=ROOT, check=True, capture_output=True,
        )  # fmt: skip
    return BASELINE_TREE / "src"


def run_child(source: Path, n_sessions: int) -> dict[str, Any]:
    """Train in a child process importing the package from ``source``; its result and peak."""
    environment = dict(os.environ, PYTHONPATH=str(source))
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(n_sessions)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=environment,
        cwd=source.parent,
    )  # fmt: skip
    loads = [os.getloadavg()[0]]
    pid, status, usage = os.wait4(child.pid, os.WNOHANG)
    while pid == 0:
        time.sleep(LOAD_EVERY)
        loads.append(os.getloadavg()[0])
        pid, status, usage = os.wait4(child.pid, os.WNOHANG)
    child.returncode = os.waitstatus_to_exitcode(status)
    stdout, stderr = child.communicate()
    if child.returncode != 0:
        raise RuntimeError(f"training under {source} failed:\n{stderr}")
    result: dict[str, Any] = json.loads(stdout.strip().splitlines()[-1])
    load = f"{sum(loads) / len(loads):.1f} (max {max(loads):.1f})"
    return result | {"peak_mb": usage.ru_maxrss / 1024, "load": load}


def measure(n_sessions: int, rounds: int) -> list[dict[str, Any]]:
    """Run the baseline and this tree alternately ``rounds`` times; one row per run."""
    baseline = baseline_tree()
    runs = []
    for round_ in range(1, rounds + 1):
        trees = [("new", ROOT / "src")]
        if baseline is not None:
            trees.insert(0, (BASELINE_COMMIT, baseline))
        for name, source in trees:
            runs.append({"tree": name, "round": round_} | run_child(source, n_sessions))
            print(f"round {round_}, {name}: {runs[-1]}", file=sys.stderr, flush=True)
    return runs


def rows(n_sessions: int, runs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Rows for `benchmarks/run.py`: each round of this tree against the baseline's."""
    new = [r for r in runs if r["tree"] == "new"]
    old = {r["round"]: r for r in runs if r["tree"] != "new"}
    out = []
    for run in new:
        before = old.get(run["round"])
        out.append(
            {
                "name": f"train, {n_sessions} sessions of 60 s, round {run['round']}",
                "value": round(run["seconds"], 1),
                "unit": "s",
                "baseline": round(before["seconds"], 1) if before else "",
                "ratio": round(before["seconds"] / run["seconds"], 2) if before else "",
                "peak_memory_mb": round(run["peak_mb"]),
                "note": f"{n_sessions / run['seconds']:.0f} sessions/s; final RMS "
                f"{run['final_rms']:.4f}, Q-table {run['q_sha256']}; load {run['load']}; "
                + (
                    f"baseline: commit {BASELINE_COMMIT}, same run, peak "
                    f"{before['peak_mb']:.0f} MB (its 2 worker processes not counted)"
                    if before
                    else f"no baseline: commit {BASELINE_COMMIT} is not in this clone"
                ),
            }
        )
    best = min(r["seconds"] for r in new) * PAPER_SESSIONS / n_sessions
    out.append(
        {
            "name": f"paper scale ({PAPER_SESSIONS} sessions), best round"
            + ("" if n_sessions == PAPER_SESSIONS else f", projected from {n_sessions}"),
            "value": round(best, 1),
            "unit": "s",
            "baseline": TARGET_SECONDS,
            "ratio": round(best / TARGET_SECONDS, 2),
            "note": f"ratio vs the issue's {TARGET_SECONDS:.0f} s target on two idle cores "
            "(< 1 meets it)",
        }
    )
    return out


def table(n_sessions: int, runs: list[dict[str, Any]]) -> str:
    """Make a Markdown table of every run, in the order run."""
    lines = [
        "| run | tree | seconds | sessions/s | ratio (baseline / new) | peak RSS (MB) | "
        "final RMS | Q-table | load average, mean (max) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    old = {r["round"]: r["seconds"] for r in runs if r["tree"] != "new"}
    for i, run in enumerate(runs, 1):
        ratio = (
            f"{old[run['round']] / run['seconds']:.2f}"
            if run["tree"] == "new" and run["round"] in old
            else ""
        )
        lines.append(
            f"| {i} | {run['tree']} | {run['seconds']:.1f} | {n_sessions / run['seconds']:.0f} | "
            f"{ratio} | {run['peak_mb']:.0f} | {run['final_rms']:.4f} | {run['q_sha256']} | "
            f"{run['load']} |"
        )
    return "\n".join(lines) + "\n"


def run(quick: bool) -> list[dict[str, Any]]:
    n_sessions = QUICK_SESSIONS if quick else PAPER_SESSIONS
    return rows(n_sessions, measure(n_sessions, rounds=2))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sessions", type=int, default=PAPER_SESSIONS)
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_SESSIONS} sessions")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--out", type=Path, help="also write the table here")
    args = parser.parse_args()
    n_sessions = QUICK_SESSIONS if args.quick else args.sessions
    before = machine()
    runs = measure(n_sessions, args.rounds)
    text = (
        f"Measured {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} "
        f"(`python benchmarks/bench_training_paper.py --sessions {n_sessions} "
        f"--rounds {args.rounds}`); {before} at the start, {machine()} at the end.\n\n"
        f"{table(n_sessions, runs)}"
    )
    if args.out is not None:
        args.out.write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
