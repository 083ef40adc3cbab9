"""``mirror-avatar train`` through the command line."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numba.core.compiler_lock import global_compiler_lock

from mirror_avatar.cli import main
from mirror_avatar.common.interruptions import interrupt
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.trial_io import write_csv_trial
from mirror_avatar.files.trials import DEFAULT_RATE
from mirror_avatar.learning.agent import load_cyber_player
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.motion.strokes import StrokeGenerator
from mirror_avatar.specs import bundled_generator
from waiting import wait_for


@pytest.fixture(autouse=True)
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Fitted bundled generators go to a per-test cache."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    bundled_generator.cache_clear()


@pytest.fixture
def models(tmp_path: Path) -> list[Path]:
    trials = [t.resampled(DEFAULT_RATE) for t in load_zhai2017()]
    paths = []
    for name, block in (("a", trials[9:12]), ("b", trials[:3]), ("c", trials[3:6])):
        path = tmp_path / f"{name}.npz"
        IMSGenerator(n_symbols=32, random_state=0).fit(block).save(path)
        paths.append(path)
    return paths


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


def _train(out: Path, target: Path, *partners: str, extra: tuple[str, ...] = ()) -> int:
    arguments = ["train", "--target", str(target), "--sessions", "6", "--duration", "5"]
    for partner in partners:
        arguments += ["--partners", partner]
    return main([*arguments, "--jobs", "1", "--out", str(out), *extra])


def test_train_writes_policy_and_curve(
    tmp_path: Path, models: list[Path], capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "policies" / "vt5.npz"
    partners = f"{models[1]},{models[2]}"
    status = _train(out, models[0], partners, extra=("--role", "leader", "--seed", "4",
                                                    "--checkpoint-every", "2"))  # fmt: skip
    assert status == 0
    printed = capsys.readouterr()
    assert str(out.resolve()) in printed.out
    checkpoint = tmp_path / "policies" / "vt5.checkpoint.npz"
    assert f"checkpoints: {checkpoint.resolve()} is saved every 2 sessions" in printed.err
    assert not checkpoint.exists(), "the finished run removes its checkpoint"
    assert out.stat().st_mode & 0o777 == 0o666 & ~_umask()
    player = load_cyber_player(out)
    assert player.training_["role"] == "leader" and player.training_["run_seed"] == 4
    assert player.training_["n_partners"] == 2 and player.training_["n_sessions"] == 6
    curve = (tmp_path / "policies" / "vt5.learning_curve.csv").read_text().splitlines()
    assert curve[0] == "sessions,mean_reward,rms,epsilon" and len(curve) == 7
    assert (tmp_path / "policies" / "vt5.learning_curve.png").read_bytes()[:4] == b"\x89PNG"
    again = tmp_path / "again.npz"
    assert _train(again, models[0], str(models[1]), str(models[2]),
                  extra=("--role", "leader", "--seed", "4")) == 0  # fmt: skip
    np.testing.assert_array_equal(load_cyber_player(again).q_table_, player.q_table_)


def test_train_takes_stroke_generator_files(tmp_path: Path, models: list[Path]) -> None:
    """A person's model fitted with the default kind trains a leader that carries it."""
    trials = [t.resampled(DEFAULT_RATE) for t in load_zhai2017()]
    target, partner = tmp_path / "strokes.npz", tmp_path / "strokes-partner.npz"
    StrokeGenerator(random_state=3).fit(trials[9:12]).save(target)
    StrokeGenerator(random_state=4).fit(trials[:3]).save(partner)
    out = tmp_path / "leader.npz"
    status = _train(out, target, str(partner), str(models[2]), extra=("--role", "leader"))
    assert status == 0
    player = load_cyber_player(out)
    assert player.training_["role"] == "leader" and player.stochastic
    assert isinstance(player.reference, StrokeGenerator)
    np.testing.assert_array_equal(
        player.reference.sample_velocity(500, 1),
        StrokeGenerator.load(target).sample_velocity(500, 1),
    )


def test_train_accepts_bundled_styles(tmp_path: Path) -> None:
    out = tmp_path / "p.npz"
    assert _train(out, Path("bundled:slow"), "bundled:fast") == 0
    assert load_cyber_player(out).training_["role"] == "follower"


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--target", "bundled:medium", "--partners", "bundled:fast"], "bundled:medium"),
        (["--target", "missing.npz", "--partners", "bundled:fast"], "missing.npz"),
        (["--target", "bundled:slow", "--partners", "bundled:fast", "--sessions", "0"], "[1, "),
        (["--target", "bundled:slow", "--partners", "bundled:fast", "--role", "joint"], "joint"),
    ],
)
def test_bad_input_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], arguments: list[str], message: str
) -> None:
    defaults = ["--sessions", "2"] if "--sessions" not in arguments else []
    status = main(["train", *arguments, *defaults, "--out", str(tmp_path / "p.npz")])
    err = capsys.readouterr().err
    assert status == 2 and message in err and len(err.strip().splitlines()) == 1


@pytest.mark.long
def test_cyber_player_model_is_not_a_training_partner(tmp_path: Path, models: list[Path]) -> None:
    policy = tmp_path / "p.npz"
    assert _train(policy, models[0], str(models[1])) == 0
    result = subprocess.run(
        [sys.executable, "-c", "from mirror_avatar.console import run; run()", "train",
         "--target", str(models[0]),
         "--partners", str(policy), "--sessions", "2", "--out", str(tmp_path / "q.npz")],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert result.returncode == 2, result.stderr
    assert "is a cyber-player policy; training needs a virtual trainer" in result.stderr
    assert "Traceback" not in result.stderr


def test_a_folder_or_a_recording_as_a_model_says_what_to_give(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A folder of trials and a trial file are not models: the line says which command helps."""
    folder = tmp_path / "alice"
    folder.mkdir()
    write_csv_trial(load_zhai2017()[0], folder / "t.csv")
    assert _train(tmp_path / "p.npz", folder, "bundled:fast") == 2
    assert f"generator fit {folder} --out MODEL.npz" in capsys.readouterr().err
    assert _train(tmp_path / "p.npz", Path("bundled:slow"), str(folder / "t.csv")) == 2
    err = capsys.readouterr().err
    assert f"give vt:{folder / 't.csv'}" in err and len(err.strip().splitlines()) == 1
    assert _train(tmp_path / "p.npz", Path("bundled:slow"), f"vt:{folder / 't.csv'}") == 0


def test_sigterm_keeps_the_finished_policy_and_stops_the_workers(
    tmp_path: Path, models: list[Path]
) -> None:
    """SIGTERM mid-training: exit 130, the earlier policy and its curve untouched, the
    checkpoint beside them loadable, and no worker process left behind."""
    out = tmp_path / "vt.npz"
    assert _train(out, models[0], str(models[1])) == 0
    before = {path: path.read_bytes() for path in tmp_path.glob("vt.*")}
    command = [sys.executable, "-X", "faulthandler", "-c",
               "from mirror_avatar.console import run; run()", "train",
               "--target", str(models[0]), "--partners", str(models[1]), "--sessions", "5000",
               "--duration", "20", "--jobs", "2", "--checkpoint-every", "4",
               "--out", str(out)]  # fmt: skip
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, start_new_session=True)
    checkpoint = tmp_path / "vt.checkpoint.npz"
    try:
        wait_for(lambda: checkpoint.exists() or process.poll() is not None, 120.0)
        assert checkpoint.exists(), "no checkpoint was written"
        process.send_signal(signal.SIGTERM)
        _, error = process.communicate(timeout=60)
    finally:
        if process.poll() is None or process.returncode != 130:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGKILL)
            _, error = process.communicate()
    assert process.returncode == 130, error
    assert "Traceback" not in error
    assert {path: path.read_bytes() for path in tmp_path.glob("vt.*")} == before | {
        checkpoint: checkpoint.read_bytes()
    }
    assert load_cyber_player(checkpoint).training_["n_sessions"] >= 4
    wait_for(lambda: group_gone(process.pid), 30.0, "the command's worker processes to end")


def group_gone(group: int) -> bool:
    """Whether no process of the process group ``group`` is left."""
    try:
        os.killpg(group, 0)
    except ProcessLookupError:
        return True
    return False


def test_an_interruption_while_compiling_waits_for_the_compiler() -> None:
    """Raised inside numba's compiler, KeyboardInterrupt can leave LLVM objects that crash the
    process when freed: the handler sends the signal again once compiling is done."""
    received: list[int] = []
    previous = signal.signal(signal.SIGUSR1, lambda signum, frame: received.append(signum))
    try:
        with global_compiler_lock:
            interrupt(signal.SIGUSR1, None)  # no exception while the lock is held
        wait_for(lambda: received, 10.0, "the signal sent again")
    finally:
        signal.signal(signal.SIGUSR1, previous)
    assert received == [signal.SIGUSR1]
    with pytest.raises(KeyboardInterrupt, match="SIGTERM"):
        interrupt(signal.SIGTERM, None)


@pytest.mark.slow
def test_sigterm_while_compiling_exits_130(tmp_path: Path, models: list[Path]) -> None:
    """A command stopped during its first compilation (an empty numba cache) exits cleanly,
    once compiling is done (about 45 s)."""
    environment = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    command = [sys.executable, "-X", "faulthandler", "-c",
               "from mirror_avatar.console import run; run()", "train",
               "--target", str(models[0]), "--partners", str(models[1]), "--sessions", "50",
               "--jobs", "1", "--out", str(tmp_path / "vt.npz")]  # fmt: skip
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, env=environment)
    try:
        numba = tmp_path / "numba"
        wait_for(lambda: any(numba.rglob("*.nbi")) or process.poll() is not None, 120.0)
        process.send_signal(signal.SIGTERM)
        _, error = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 130, error
    assert "Traceback" not in error and "Fatal Python error" not in error
    assert not (tmp_path / "vt.npz").exists()
