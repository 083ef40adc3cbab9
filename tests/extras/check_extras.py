"""Each optional extra's commands run with that extra, on a fresh virtual environment.

    python tests/extras/check_extras.py [--keep DIR]

Creates a virtual environment without the ``dev`` extra and installs the package in layers,
running after each the tutorial's and guides' commands that the layer's extra should make work:

1. ``pip install .`` (no extra; from a copy of the sources, so no build folder is left in the
   tree): ``--help``, the signatures of the bundled data; ``lab pilot`` and
   ``train --scheduler`` refused in one line naming the extra to install (exit code 2).
2. ``pip install -e ".[live]"``: ``lab preview`` of the tutorial's study, the tutorial's
   generator and the study piloted with it (the trials shortened to 2 s).
3. ``".[rl]"``: a simulated session evaluated, the Gymnasium environment reset and stepped on
   it, the PettingZoo one.
4. ``".[cluster]"``: a scheduler and a worker on loopback (the rehearsal of docs/cluster.md)
   playing a short training.
5. ``".[lsl]"``: an LSL outlet of a lab trial opened.
6. ``".[all]"``: what the documented install adds to all of them (nothing, if ``all`` holds
   every extra).

Each layer adds its extra to the ones before, so the ``live`` commands run with ``live`` alone.
The installs skip compiling the bytecode (``--no-compile``: Python compiles what a command
imports). The editable installs use the numeric kernels' cache of the source tree, which
``make`` fills (`mirror_avatar.warm_up`); the copy of the first layer has none, so its commands
are those that compile little. `.ci/run` runs this after ``make test`` (``make extras``), not
``make test`` itself: it installs from the registries, minutes on a busy machine. It prints a
line per check (wall time, and CPU time of its processes) and closes with
``extras: N passed, N failed``; its exit code is 1 if any failed.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import venv
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TUTORIAL = ROOT / "docs" / "tutorial.md"
TIMEOUT = 600
SHORT_TRIAL = 2

RL_STEPS = """
from mirror_avatar.rl.env import MirrorGameEnv
from mirror_avatar.rl.multi_agent import MirrorGroupEnv
from mirror_avatar.sessions.loading import load_session

env = MirrorGameEnv([load_session("session/session.parquet")])
observation, info = env.reset(seed=1)
for _ in range(20):
    observation, reward, done, truncated, info = env.step(env.action_space.sample())
group = MirrorGroupEnv(n_agents=2, duration=2.0)
observations, infos = group.reset(seed=1)
print("rl", observation.shape, sorted(observations))
"""

LSL_OUTLET = """
import pylsl
from mirror_avatar.lab.running.lsl import SessionOutlet

with SessionOutlet("check", "check-1", ["P1", "A1"], ["leader", "follower"],
                   ["human", "avatar"], 0.03) as outlet:
    outlet.push_positions([0.0, 0.1])
print("lsl", pylsl.library_version())
"""


class Checks:
    """Runs commands in one environment and folder, and counts what passed."""

    def __init__(self, environment: Path, folder: Path) -> None:
        self.bin = environment / "bin"
        self.folder = folder
        self.passed = 0
        self.failed: list[str] = []

    def run(self, *arguments: str | Path) -> subprocess.CompletedProcess[str]:
        """Run a program of the environment (its name first) in the folder."""
        program, *rest = arguments
        return subprocess.run(
            [str(self.bin / program), *map(str, rest)], cwd=self.folder, capture_output=True,
            text=True, timeout=TIMEOUT, check=False, env=clean_environment(),
        )  # fmt: skip

    def check(self, name: str, done: Callable[[], str | None]) -> None:
        """Run ``done``, which returns None when the check passed and what failed otherwise."""
        start, cpu = time.perf_counter(), children_cpu()
        problem = done()
        took = f"{time.perf_counter() - start:.0f} s, CPU {children_cpu() - cpu:.0f} s"
        if problem is None:
            self.passed += 1
            print(f"ok    {name} ({took})", flush=True)
        else:
            self.failed.append(name)
            print(f"FAIL  {name} ({took}): {problem}", flush=True)

    def command(self, name: str, *arguments: str | Path, status: int = 0, says: str = "") -> None:
        """Check that a command ends with ``status`` and prints ``says`` (stdout or stderr)."""

        def done() -> str | None:
            result = self.run(*arguments)
            shown = result.stdout + result.stderr
            if result.returncode != status or says not in shown:
                tail = " | ".join(shown.strip().splitlines()[-3:])
                wanted = f"{status}, {says!r}" if says else f"{status}"
                return f"exit {result.returncode} (wanted {wanted}): {tail}"
            return None

        self.check(name, done)

    def install(self, name: str, *requirements: str) -> None:
        """Install into the environment, skipping the bytecode's compilation."""
        self.command(
            name, "python", "-m", "pip", "install", "--quiet", "--no-compile", *requirements
        )


def children_cpu() -> float:
    """User and system time of the ended child processes, in seconds."""
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    return used.ru_utime + used.ru_stime


def copy_sources(destination: Path) -> Path:
    """Copy what ``pip install .`` builds from (no caches, no build products) to ``destination``."""
    skip = shutil.ignore_patterns("__pycache__", "*.egg-info", "*.nbi", "*.nbc")
    destination.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        if (ROOT / name).is_file():
            shutil.copy2(ROOT / name, destination / name)
    shutil.copytree(ROOT / "src", destination / "src", ignore=skip)
    return destination


def clean_environment() -> dict[str, str]:
    """The environment a person's shell would have: no PYTHONPATH, no virtual environment."""
    removed = ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")
    return {key: value for key, value in os.environ.items() if key not in removed}


def tutorial_study(trial_seconds: int | None = None) -> str:
    """The tutorial's study protocol (its trials shortened to ``trial_seconds`` if given)."""
    text = TUTORIAL.read_text(encoding="utf-8")
    protocol = re.search(r"cat > first-study.toml <<'EOF'\n(.*?)\nEOF\n", text, re.DOTALL)
    if protocol is None:
        raise SystemExit(f"{TUTORIAL}: no first-study.toml")
    study = protocol.group(1) + "\n"
    if trial_seconds is not None:
        study = re.sub(r"(?m)^duration = \d+$", f"duration = {trial_seconds}", study)
    return study


def free_port() -> int:
    """A port nothing listens on now, on loopback."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def wait_for_port(port: int, within: float = 120.0) -> bool:
    """Wait until something accepts connections on ``port`` of loopback."""
    end = time.monotonic() + within
    while time.monotonic() < end:
        with socket.socket() as sock:
            if sock.connect_ex(("127.0.0.1", port)) == 0:
                return True
        time.sleep(0.5)
    return False


def core(checks: Checks) -> None:
    """The package without extras: the core commands run, the others name their extra."""
    checks.command("--help lists the commands", "mirror-avatar", "--help", says="signature")
    checks.command(
        "signature of the bundled data", "mirror-avatar", "signature", "--bundled",
        "--out", "signature", says="people",
    )  # fmt: skip
    checks.command(
        "lab pilot without live names the extra", "mirror-avatar", "lab", "pilot", "--protocol",
        "short-study.toml", "--participants", "1", "--out", "refused",
        status=2, says="pip install 'mirror-avatar[live]'",
    )  # fmt: skip
    checks.command(
        "train --scheduler without cluster names the extra", "mirror-avatar", "train",
        "--target", "bundled:slow", "--partners", "bundled:fast", "--sessions", "2",
        "--scheduler", "tcp://127.0.0.1:9", "--out", "refused.npz",
        status=2, says="pip install 'mirror-avatar[cluster]'",
    )  # fmt: skip


def live(checks: Checks) -> None:
    """The tutorial's study previewed, its generator, the study piloted with it."""
    checks.command(
        "lab preview (tutorial)", "mirror-avatar", "lab", "preview", "--protocol",
        "first-study.toml", "--participants", "4", says="immediate",
    )  # fmt: skip
    checks.command(
        "generator fit (tutorial)", "mirror-avatar", "generator", "fit", "--bundled", "slow",
        "--kind", "ims", "--symbols", "64", "--seed", "1", "--out", "slow.npz",
    )  # fmt: skip
    checks.command(
        "lab pilot (tutorial, 2 s trials)", "mirror-avatar", "lab", "pilot", "--protocol",
        "short-study.toml", "--participants", "1", "--stand-in", "P1=slow.npz", "--seed", "1",
        "--out", "pilot",
    )  # fmt: skip


def rl(checks: Checks) -> None:
    """A session simulated and evaluated, then the Gymnasium and PettingZoo environments."""
    checks.command(
        "simulate (tutorial)", "mirror-avatar", "simulate", "--leader", "slow.npz",
        "--follower", "bundled:fast", "--duration", "20", "--seed", "1", "--out", "session",
    )  # fmt: skip
    checks.command("evaluate (tutorial)", "mirror-avatar", "evaluate", "session",
                   "--out", "evaluation")  # fmt: skip
    checks.command("rl environments step", "python", "-c", RL_STEPS, says="rl ")


def cluster(checks: Checks) -> None:
    """A scheduler and a worker on loopback playing a short training (docs/cluster.md)."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    log = (checks.folder / "dask.log").open("w")
    started = [
        subprocess.Popen(
            [str(checks.bin / "dask"), *arguments], cwd=checks.folder, stdout=log, stderr=log,
            env=clean_environment(),
        )  # fmt: skip
        for arguments in (
            ["scheduler", "--host", "127.0.0.1", "--port", str(port),
             "--dashboard-address", "127.0.0.1:0"],
            ["worker", address, "--host", "127.0.0.1", "--dashboard-address", "127.0.0.1:0",
             "--nthreads", "1"],
        )
    ]  # fmt: skip
    try:
        if not wait_for_port(port):
            checks.check("dask scheduler listens", lambda: "no scheduler; see dask.log")
            return
        checks.command(
            "train on a dask worker", "mirror-avatar", "train", "--target", "slow.npz",
            "--partners", "bundled:fast", "--sessions", "4", "--duration", "5",
            "--scheduler", address, "--out", "follower.npz",
        )  # fmt: skip
    finally:
        for process in reversed(started):
            process.terminate()
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        log.close()


def lsl(checks: Checks) -> None:
    """An LSL outlet of a lab trial."""
    checks.command("lsl outlet", "python", "-c", LSL_OUTLET, says="lsl ")


LAYERS: list[tuple[str, Callable[[Checks], None]]] = [
    ("live", live), ("rl", rl), ("cluster", cluster), ("lsl", lsl),
]  # fmt: skip


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", type=Path, help="work in this new folder and keep it")
    options = parser.parse_args()
    if options.keep:
        options.keep.mkdir(parents=True)
        work = options.keep.resolve()
    else:
        work = Path(tempfile.mkdtemp(prefix="mirror-avatar-extras-"))
    environment, folder = work / "venv", work / "run"
    folder.mkdir()
    (folder / "first-study.toml").write_text(tutorial_study(), encoding="utf-8")
    (folder / "short-study.toml").write_text(tutorial_study(SHORT_TRIAL), encoding="utf-8")
    checks = Checks(environment, folder)
    start = time.perf_counter()
    try:
        venv.create(environment, with_pip=True)
        checks.install("pip install . (no extra)", str(copy_sources(work / "source")))
        if not checks.failed:
            core(checks)
            for extra, run in LAYERS:
                checks.install(f'pip install -e ".[{extra}]"', "-e", f"{ROOT}[{extra}]")
                run(checks)
            checks.install('pip install -e ".[all]"', "-e", f"{ROOT}[all]")
    finally:
        if not options.keep:
            shutil.rmtree(work, ignore_errors=True)
    print(f"extras: {time.perf_counter() - start:.0f} s in all, CPU {children_cpu():.0f} s")
    print(f"extras: {checks.passed} passed, {len(checks.failed)} failed")
    return 1 if checks.failed else 0


if __name__ == "__main__":
    sys.exit(main())
