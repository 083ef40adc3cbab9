"""``mirror-avatar avatar create``: a person's avatar from solo trials, playable as a SPEC."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.deep.player import DeepCyberPlayer
from mirror_avatar.errors import InputError
from mirror_avatar.generator import IMSGenerator
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.live.session import make_avatar_factory
from mirror_avatar.model_files import load_model, save_model
from mirror_avatar.players import VirtualTrainer
from mirror_avatar.specs import bundled_generator, load_player
from mirror_avatar.training.avatar import load_avatar
from mirror_avatar.trial_io import write_csv_trial


@pytest.fixture(autouse=True)
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    bundled_generator.cache_clear()


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An avatar of a person outside the bundled data (motion generated in a slow style)."""
    folder = tmp_path_factory.mktemp("avatar")
    source = IMSGenerator(n_symbols=64, random_state=7).fit(load_zhai2017()[9:13])
    (folder / "trials").mkdir()
    for k, trial in enumerate(source.sample(30.0, 3, random_state=11)):
        write_csv_trial(trial, folder / "trials" / f"trial{k}.csv")
    fast, slow = (folder / "fast.npz", folder / "slow.npz")
    IMSGenerator(n_symbols=32, random_state=0).fit(load_zhai2017()[:3]).save(fast)
    IMSGenerator(n_symbols=32, random_state=0).fit(load_zhai2017()[15:18]).save(slow)
    out = folder / "P01.npz"
    status = main(["avatar", "create", str(folder / "trials"), "--name", "P01", "--partners",
                   f"{fast},{slow}", "--sessions", "40", "--jobs", "1",
                   "--out", str(out)])  # fmt: skip
    assert status == 0
    return out


def rewrite_avatar(path: Path, arrays: dict, metadata: dict) -> Path:
    """Write an avatar file with edited arrays and metadata (its format header made afresh)."""
    for key in ("format", "version", "library_version"):
        metadata.pop(key, None)
    return save_model(path, "mirror-avatar/avatar", 1, arrays, metadata)


def test_the_avatar_file_holds_both_roles_and_its_card(built: Path) -> None:
    avatar = load_avatar(built)
    assert avatar.name == "P01" and set(avatar.players) == {"follower", "leader"}
    assert avatar.summary["unseen_partner"].endswith("slow.npz")
    assert avatar.summary["n_sessions"] == 40 and avatar.summary["seed"] == 0
    assert avatar.generator.training_summary_["complexity"]["rule"].startswith("cross-validation")
    for role in ("follower", "leader"):
        assert set(avatar.summary["roles"][role]) >= {"emd_to_person", "unseen_cv_difference"}
    card = built.with_suffix(".html").read_text()
    assert "Avatar of P01" in card and "Table I" in card and "data:image/png;base64" in card


def test_the_session_role_picks_the_player(built: Path) -> None:
    follower, leader = load_player(str(built), "follower"), load_player(str(built), "leader")
    assert isinstance(follower, CyberPlayer) and follower.training_["role"] == "follower"
    assert isinstance(leader, CyberPlayer) and leader.training_["role"] == "leader"
    assert isinstance(load_player(str(built), "joint"), VirtualTrainer)


def test_the_avatar_plays_in_simulate(built: Path, tmp_path: Path) -> None:
    out = tmp_path / "session"
    status = main(["simulate", "--leader", "bundled:fast", "--follower", str(built),
                   "--duration", "5", "--seed", "2", "--out", str(out)])  # fmt: skip
    assert status == 0
    result = json.loads((out / "metrics.json").read_text())
    assert str(built) in json.dumps(result["specs"]) and np.isfinite(result["metrics"]["rmse"])
    assert np.isfinite(result["metrics"]["emd_target_1"])


def test_a_damaged_avatar_is_refused_in_one_line(built: Path, tmp_path: Path) -> None:
    """Its follower swapped for its leader: each part is checked as its own file would be."""
    arrays, metadata = load_model(built, "mirror-avatar/avatar", 1, ())
    swapped = {k: a for k, a in arrays.items() if not k.startswith("follower__")}
    leader = {k.removeprefix("leader__"): a for k, a in arrays.items() if k.startswith("leader__")}
    swapped |= {f"follower__{k}": a for k, a in leader.items()}
    metadata["follower"] = metadata["leader"]
    damaged = rewrite_avatar(tmp_path / "damaged.npz", swapped, metadata)
    with pytest.raises(InputError, match="its follower was trained as 'leader'"):
        load_avatar(damaged)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--partners", "bundled:fast"], "at least two partners"),
        (["--name", " "], "is not a name"),
        (["--sessions", "0"], ">= 1"),
    ],
)
def test_bad_options_are_one_line_before_any_work(tmp_path, capsys, extra, message) -> None:
    trial = load_zhai2017()[0]
    write_csv_trial(trial, tmp_path / "t.csv")
    arguments = ["avatar", "create", str(tmp_path / "t.csv"), "--name", "P", "--out",
                 str(tmp_path / "a.npz"), *extra]  # fmt: skip
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and message in error
    assert not (tmp_path / "a.npz").exists()


def test_live_play_takes_the_avatar_in_every_mode(built: Path) -> None:
    factory = make_avatar_factory(str(built))
    assert factory("avatar_follows").training_["role"] == "follower"  # type: ignore[attr-defined]
    assert factory("avatar_leads").training_["role"] == "leader"  # type: ignore[attr-defined]
    assert isinstance(factory("joint"), VirtualTrainer)


def test_a_deep_avatar_is_built_saved_and_played(built: Path, tmp_path: Path) -> None:
    folder = built.parent
    out = tmp_path / "P01-deep.npz"
    status = main(["avatar", "create", str(folder / "trials"), "--name", "P01", "--partners",
                   f"{folder / 'fast.npz'},{folder / 'slow.npz'}", "--agent", "dqn",
                   "--sessions", "3", "--jobs", "1", "--out", str(out)])  # fmt: skip
    assert status == 0
    avatar = load_avatar(out)
    assert avatar.summary["agent"] == "dqn" and avatar.summary["n_sessions"] == 3
    for role in ("follower", "leader"):
        player = load_player(str(out), role)
        assert isinstance(player, DeepCyberPlayer) and player.training_["role"] == role
        np.testing.assert_array_equal(player.weights_, avatar.players[role].weights_)
    assert avatar.players["leader"].needs_reference and avatar.players["leader"].stochastic
    assert "deep cyber player" in out.with_suffix(".html").read_text()
    arrays, metadata = load_model(out, "mirror-avatar/avatar", 1, ())
    metadata["leader"]["agent"] = "transformer"
    unknown = rewrite_avatar(tmp_path / "unknown.npz", arrays, metadata)
    with pytest.raises(InputError, match="agent 'transformer' is not one of 'tabular' or 'dqn'"):
        load_avatar(unknown)
