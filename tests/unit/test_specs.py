"""Tests of player specs: every form of SPEC, the bundled-generator cache and bad specs."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar import dynamics, specs
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trial_files import write_trial
from mirror_avatar.files.trials import Trial
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.players import Observation, Player, RecordedPlayer, VirtualTrainer, check_player
from mirror_avatar.specs import bundled_generator, cache_dir, load_player


@pytest.fixture(autouse=True)
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """Each test gets an empty on-disk and in-process cache of bundled generators."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    bundled_generator.cache_clear()
    yield tmp_path / "cache" / "mirror-avatar"
    bundled_generator.cache_clear()


def _run(player: Player, seed: int, n_steps: int = 100) -> np.ndarray:
    states = [player.reset(seed)]
    for k in range(n_steps):
        x = 0.2 * np.sin(0.1 * k)
        states.append(player.step(Observation.of_partner(k, x, 0.0, x)))
    return np.asarray(states)


@pytest.mark.long
def test_bundled_spec_is_a_virtual_trainer_of_that_style(zhai_trials_100hz: list[Trial]):
    player = load_player("bundled:fast", "leader")
    assert isinstance(player, VirtualTrainer)
    assert player.params == dynamics.LEADER
    summary = player.reference.training_summary_  # type: ignore[union-attr]
    assert set(summary["groups"]) == {"fast"}
    assert bundled_generator("fast") is player.reference
    check_player(lambda: load_player("bundled:slow", dynamics.FOLLOWER))


def test_bundled_generator_is_cached_on_disk(
    private_cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    fitted = bundled_generator("slow")
    files = list(private_cache.glob("bundled-slow-*.npz"))
    assert cache_dir() == private_cache and len(files) == 1
    bundled_generator.cache_clear()

    def no_data() -> list[Trial]:
        raise AssertionError("the cached model should have been read, not refitted")

    monkeypatch.setattr(specs, "load_zhai2017", no_data)
    cached = bundled_generator("slow")
    assert cached is not fitted
    np.testing.assert_array_equal(cached.transmat_, fitted.transmat_)
    np.testing.assert_array_equal(cached.codebook_, fitted.codebook_)


def test_corrupt_cache_file_is_refitted(private_cache: Path) -> None:
    fitted = bundled_generator("fast")
    (path,) = private_cache.glob("bundled-fast-*.npz")
    path.write_bytes(path.read_bytes()[:200])
    bundled_generator.cache_clear()
    refitted = bundled_generator("fast")
    np.testing.assert_array_equal(refitted.transmat_, fitted.transmat_)
    np.testing.assert_array_equal(IMSGenerator.load(path).transmat_, fitted.transmat_)


def test_unwritable_cache_still_gives_a_generator(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("x")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    assert bundled_generator("slow").transmat_.shape == (256, 256)


def test_generator_model_file(tmp_path: Path, zhai_trials_100hz: list[Trial]) -> None:
    model = IMSGenerator(n_symbols=16, random_state=1).fit(zhai_trials_100hz[:3])
    path = tmp_path / "model.npz"
    model.save(path)
    player = load_player(str(path), "joint")
    assert isinstance(player, VirtualTrainer) and player.params == dynamics.JOINT
    np.testing.assert_array_equal(player.reference.transmat_, model.transmat_)  # type: ignore[union-attr]


def test_cyber_player_file(tmp_path: Path, rng: np.random.Generator) -> None:
    trained = CyberPlayer()
    trained.initialise_q(rng, scale=1.0)
    path = trained.save(tmp_path / "policy.npz")
    player = load_player(str(path), "follower")
    assert isinstance(player, CyberPlayer)
    np.testing.assert_array_equal(player.q_table_, trained.q_table_)
    np.testing.assert_array_equal(_run(player, 3), _run(trained, 3))


def test_recorded_trial_is_replayed(tmp_path: Path, zhai_trials: list[Trial]) -> None:
    path = tmp_path / "person.csv"
    write_trial(zhai_trials[0], path)
    trial = zhai_trials[0].resampled(100.0)
    player = load_player(str(path), "leader")
    assert isinstance(player, RecordedPlayer)
    states = _run(player, 0, n_steps=50)
    times = np.arange(51) * player.period
    expected = np.interp(times, trial.times - trial.times[0], trial.positions)
    np.testing.assert_allclose(states[:, 0], expected, atol=1e-9)


def test_vt_spec_uses_the_recording_as_reference(tmp_path: Path, zhai_trials: list[Trial]) -> None:
    path = tmp_path / "person.parquet"
    write_trial(zhai_trials[4], path)
    player = load_player(f"vt:{path}", "leader")
    assert isinstance(player, VirtualTrainer) and isinstance(player.reference, Trial)
    reference = player.draw_reference(0, 400)
    expected = zhai_trials[4].resampled(100.0)
    times = np.arange(400) * player.period
    np.testing.assert_allclose(
        reference, np.interp(times, expected.times - expected.times[0], expected.velocity())
    )


@pytest.mark.parametrize(
    ("spec", "problem"),
    [
        ("bundled:medium", "unknown bundled style"),
        ("nobody", "not a player spec"),
        ("vt:missing.csv", "no such file"),
        ("missing.npz", "no such file"),
        ("trial.txt", "not a player spec"),
    ],
)
def test_bad_specs(spec: str, problem: str) -> None:
    with pytest.raises(InputError, match=problem) as raised:
        load_player(spec, "leader")
    assert str(raised.value).startswith(spec.removeprefix("vt:"))


def test_npz_of_another_format(tmp_path: Path) -> None:
    path = tmp_path / "other.npz"
    np.savez(path, metadata=np.array('{"format": "someone-else/model"}'))
    with pytest.raises(InputError, match="is none of"):
        load_player(str(path), "leader")
    np.savez(path, values=np.zeros(3))
    with pytest.raises(InputError, match="no metadata"):
        load_player(str(path), "leader")


def test_unknown_role() -> None:
    with pytest.raises(InputError, match="unknown role"):
        load_player("bundled:slow", "captain")


@pytest.mark.parametrize(
    ("trained", "allowed", "refused"),
    [
        ("follower", "follower", "leader"),
        ("leader", "leader", "joint"),
        ("group", "joint", "follower"),
    ],
)
def test_a_policy_plays_only_the_role_it_was_trained_for(tmp_path, trained, allowed, refused):
    player = CyberPlayer()
    player.initialise_q(0, 1.0)
    player.training_ = {"role": trained}
    path = player.save(tmp_path / "policy.npz")
    assert isinstance(load_player(str(path), allowed), CyberPlayer)
    with pytest.raises(InputError, match=f"trained as {trained} cannot play {refused}"):
        load_player(str(path), refused)


@pytest.mark.parametrize(
    ("spec", "replays"),
    [
        ("trials/P07.csv", True),
        ("./kuramoto", True),
        ("vt:trials/P07.csv", False),
        ("P07.npz", False),
        ("bundled:slow", False),
        ("kuramoto:coupling=0.5", False),
    ],
)
def test_only_a_trial_file_given_as_a_spec_replays_a_recording(spec: str, replays: bool):
    assert specs.replays_recording(spec) is replays
