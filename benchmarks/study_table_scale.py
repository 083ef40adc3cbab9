"""``study table`` (and ``study report`` on its table) of a study of 500 dyads x 20 trials.

The study:

- **Recorded**: `PROTOCOL`, a dyad of two people in two conditions (``lead``: P1 leads;
  ``joint``), one 20 s trial each at the lab's rate (33.3 Hz, 668 samples), each followed by
  a person-or-computer question and a confidence rating, in a Latin-square order, is played
  through the real lab server by `mirror_avatar.lab.running.pilot.run_pilot` for participants
  0 and 1 (stand-ins ``bundled:slow`` as P1, ``bundled:fast`` as P2; pilot seed `SEED`): four
  recorded trials, every file as the lab writes it (``study.json``, each trial's session CSV and
  sidecar, inputs, pointer and view files, answers, ``ended.json``). About 90 s.
- **Copied and varied**: participant p's run is participant ``p % 2``'s recorded run, each of
  its two conditions played `TRIALS` / 2 times in a row. Each copy of a trial is the recorded
  session with its four channels (positions, velocities, controls, references) rolled in time
  by an offset of 0 to n - 1 samples drawn from ``numpy.random.default_rng([SEED, p, n])``,
  and its record's session id, participant, trial number, condition trial, file names and
  surrogate seed (drawn from the same generator) set to the copy's; it is written by
  `mirror_avatar.sessions.session.Session.save_csv` (session CSV and sidecar). The trial's
  inputs, pointer and view files are the recorded ones copied; its answers and the run's
  ``study.json`` and ``ended.json`` are the recorded ones with the trial numbers and
  participant changed, written by `mirror_avatar.files.atomic.write_atomic_json`.
- **Timed**: ``mirror-avatar study table DIR --out OUT`` (default trim and surrogates) on the
  first `BASELINE_PARTICIPANTS` participants' runs (the baseline, same run) and on all of
  them, then ``mirror-avatar study report`` on the table of all, each in a fresh child process
  (interpreter start and imports included). Wall time; CPU time (user + system, of the child
  and the workers it waited for, from ``/usr/bin/time -v``: on a shared machine the measure
  that does not depend on the load); peak memory = the largest sum of the
  resident memory (RSS) of the child and all its descendants, and the largest sum of their
  proportional memory (PSS: a page shared by forked workers counted once), sampled every
  `SAMPLE_S` s with psutil (worker processes count); ``ru_maxrss`` of the largest single
  process from ``/usr/bin/time -v`` beside it. Ratio = each table's time / the first's.

Run: ``PYTHONPATH=src python benchmarks/study_table_scale.py [--participants 500]
[--source OTHER/src]`` (``--source`` times another checkout's package on the same study, e.g.
main's, exported with ``git archive``). Prints one Markdown row per command and the load.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil

from mirror_avatar.files.atomic import write_atomic_json
from mirror_avatar.lab.running.pilot import run_pilot
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.sessions.session import Session

SEED = 51
"""The pilot's seed and the copies' generator seed."""

TRIALS = 20
"""Trials per participant: each of the two conditions played half as many times."""

BASELINE_PARTICIPANTS = 50
"""Participants of the baseline table."""

SAMPLE_S = 0.1
"""How often the children's resident memory is sampled (s)."""

ENTRY = "from mirror_avatar.console import run; run()"
"""The console script's entry point, run by each child."""

COMPANIONS = ("_inputs.csv", "_pointer.csv", "_view.csv")
"""A trial's files copied as recorded."""

PROTOCOL = """title = "dyads"
seed = 51
[questions.partner]
text = "Was your partner a person or a computer?"
kind = "choice"
options = ["a person", "a computer"]
[questions.confidence]
text = "How sure are you?"
kind = "likert"
points = 7
anchors = ["guessing", "certain"]
[[blocks]]
name = "dyad"
order = "latin"
[[blocks.conditions]]
name = "lead"
game = "leader_follower"
players = [{ label = "P1", kind = "person" }, { label = "P2", kind = "person" }]
leaders = ["P1"]
trials = 1
duration = 20
pause = 0
show_metrics = false
after_trial = ["partner", "confidence"]
[[blocks.conditions]]
name = "joint"
game = "joint"
players = [{ label = "P1", kind = "person" }, { label = "P2", kind = "person" }]
trials = 1
duration = 20
pause = 0
show_metrics = false
after_trial = ["partner", "confidence"]
"""


def record(folder: Path) -> list[Path]:
    """Play participants 0 and 1 through the lab server; return their run folders."""
    folder.mkdir(parents=True, exist_ok=True)
    protocol = folder / "dyads.toml"
    protocol.write_text(PROTOCOL)
    run_pilot(protocol, folder / "runs", range(2), {"P1": "bundled:slow", "P2": "bundled:fast"},
              SEED)  # fmt: skip
    return sorted((folder / "runs").glob("dyads-p*"))


def expand(templates: list[Path], out: Path, participants: int) -> None:
    """Write ``participants`` runs of `TRIALS` trials copied from ``templates`` (docstring)."""
    for p in range(participants):
        template = templates[p % len(templates)]
        run = out / f"dyads-p{p:03d}"
        run.mkdir(parents=True)
        played = sorted(template.glob("trial-*_session.csv"))
        per_condition = TRIALS // len(played)
        for c, recorded in enumerate(played):
            session = load_session(recorded)
            for j in range(per_condition):
                n = c * per_condition + j + 1
                _copy_trial(session, recorded, run, p, n, j + 1)
        _copy_run_files(template, run, p, per_condition)


def _copy_trial(session: Session, recorded: Path, run: Path, p: int, n: int, nth: int) -> None:
    rng = np.random.default_rng([SEED, p, n])
    shift = int(rng.integers(session.n_samples))
    stem = f"trial-{n:02d}"
    metadata = json.loads(json.dumps(session.metadata))
    metadata["lab"] |= {"session_id": run.name, "participant": p, "trial": n,
                        "condition_trial": nth}  # fmt: skip
    metadata["files"] = {k: f"{stem}_{k}.csv" for k in metadata["files"]}
    metadata["seed"] = int(rng.integers(2**31))
    rolled = {
        name: np.roll(getattr(session, name), shift, axis=1)
        for name in ("positions", "velocities", "controls", "references")
    }
    copy = Session(session.times, **rolled, labels=session.labels, roles=session.roles,
                   graph=session.graph, metadata=metadata)  # fmt: skip
    copy.save_csv(run / f"{stem}_session.csv")
    source = recorded.name.removesuffix("_session.csv")
    for suffix in COMPANIONS:
        shutil.copyfile(recorded.with_name(source + suffix), run / f"{stem}{suffix}")
    answers = json.loads(recorded.with_name(f"{source}_answers.json").read_text())
    write_atomic_json(run / f"{stem}_answers.json", answers | {"trial": n})


def _copy_run_files(template: Path, run: Path, p: int, per_condition: int) -> None:
    study = json.loads((template / "study.json").read_text())
    study |= {"id": run.name, "participant": p}
    for c, entry in enumerate(study["order"]):
        entry["trials"] = list(range(c * per_condition + 1, (c + 1) * per_condition + 1))
        entry["plan"]["trials"] = per_condition
    write_atomic_json(run / "study.json", study)
    ended = template / "ended.json"
    if ended.is_file():
        write_atomic_json(run / "ended.json", json.loads(ended.read_text()))


def timed(command: list[str], source: Path) -> dict[str, float]:
    """Run ``command`` in a child; return its wall time (s) and peak memory (MB, see above)."""
    env = os.environ | {"PYTHONPATH": str(source)}
    full = ["/usr/bin/time", "-v", sys.executable, "-c", ENTRY, *command]
    started = time.monotonic()
    child = psutil.Popen(full, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    peak, peak_pss = 0, 0
    while child.poll() is None:
        rss, pss = _tree_memory(child)
        peak, peak_pss = max(peak, rss), max(peak_pss, pss)
        time.sleep(SAMPLE_S)
    wall = time.monotonic() - started
    out, err = child.communicate()
    if child.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed ({child.returncode}):\n{out}\n{err}")
    largest = re.search(r"Maximum resident set size \(kbytes\): (\d+)", err)
    cpu = sum(float(t) for t in re.findall(r"(?:User|System) time \(seconds\): ([\d.]+)", err))
    return {"wall_s": wall, "cpu_s": cpu, "peak_mb": peak / 1e6, "peak_pss_mb": peak_pss / 1e6,
            "largest_mb": int(largest.group(1)) / 1e3 if largest else float("nan")}  # fmt: skip


def _tree_memory(process: psutil.Process) -> tuple[int, int]:
    """Return the resident and proportional memory of ``process`` and its descendants (bytes).

    The proportional set size (PSS) counts a page shared by k processes (a forked worker's
    copy of the package) as 1/k in each, so its sum counts it once; 0 once the process is gone.
    """
    rss = pss = 0
    try:
        for each in [process, *process.children(recursive=True)]:
            memory = each.memory_full_info()
            rss, pss = rss + memory.rss, pss + memory.pss
    except psutil.NoSuchProcess:
        pass
    return rss, pss


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participants", type=int, default=500)
    parser.add_argument("--sizes", type=int, nargs="+", help="participants of each table timed "
                        f"(default {BASELINE_PARTICIPANTS} and --participants)")  # fmt: skip
    parser.add_argument("--jobs", type=int, default=1, help="study table --jobs")
    parser.add_argument("--surrogates", type=int, help="study table --surrogates (its default)")
    parser.add_argument("--no-report", action="store_true", help="time the tables only")
    parser.add_argument("--source", type=Path, default=Path(__file__).parents[1] / "src")
    parser.add_argument("--recorded", type=Path, help="a folder record() wrote, to reuse")
    parser.add_argument("--keep", type=Path, help="write the study here and keep it")
    args = parser.parse_args()
    sizes = args.sizes or [BASELINE_PARTICIPANTS, args.participants]
    options = [] if args.jobs == 1 else ["--jobs", str(args.jobs)]
    if args.surrogates is not None:
        options += ["--surrogates", str(args.surrogates)]
    rows: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as scratch:
        work = args.keep or Path(scratch)
        recorded = args.recorded or work / "recorded"
        templates = sorted((recorded / "runs").glob("dyads-p*")) or record(recorded)
        study = work / "study"
        if not study.is_dir():
            started = time.monotonic()
            expand(templates, study, max(sizes))
            print(f"wrote {max(sizes)} x {TRIALS} trials in {time.monotonic() - started:.0f} s")
        load = os.getloadavg()
        for size in sizes:
            runs = work / f"first-{size}"
            if not runs.is_dir():
                runs.mkdir()
                for run in sorted(study.iterdir())[:size]:
                    os.symlink(run.resolve(), runs / run.name)
            out = Path(scratch) / f"table-{size}"
            rows[f"table, {size} x {TRIALS}{' '.join(['', *options])}"] = timed(
                ["study", "table", str(runs), "--out", str(out), *options], args.source
            )
            print(rows, flush=True)
        if not args.no_report:
            rows[f"report, {max(sizes)} x {TRIALS}"] = timed(
                ["study", "report", str(out), "--out", str(Path(scratch) / "report")], args.source
            )
        load_after = os.getloadavg()
    base = next(iter(rows.values()))["wall_s"]
    print("| command | wall (s) | ratio to the first | CPU, user + system (s) | peak RSS, all "
          "processes (MB) | peak PSS, all processes (MB) | largest process (MB) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for name, row in rows.items():
        print(f"| {name} | {row['wall_s']:.1f} | {row['wall_s'] / base:.1f} | {row['cpu_s']:.0f} | "
              f"{row['peak_mb']:.0f} | {row['peak_pss_mb']:.0f} | "
              f"{row['largest_mb']:.0f} |")  # fmt: skip
    print(f"load (1, 5, 15 min) before {load}, after {load_after}; {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
