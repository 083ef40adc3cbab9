"""``mirror-avatar avatar create``: a person's avatar from solo trials, playable as a SPEC."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.deep.player import DeepCyberPlayer
from mirror_avatar.engine.loop import play
from mirror_avatar.files.model_files import load_model, save_model
from mirror_avatar.files.trial_io import write_csv_trial
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.live.session import make_avatar_factory
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.motion.strokes import StrokeGenerator
from mirror_avatar.players import RecordedPlayer, VirtualTrainer
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.specs import bundled_generator, load_player
from mirror_avatar.training.avatar import load_avatar


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


@pytest.mark.long
def test_the_avatar_file_holds_both_roles_and_its_card(built: Path) -> None:
    avatar = load_avatar(built)
    assert avatar.name == "P01" and set(avatar.players) == {"follower", "leader"}
    assert avatar.summary["unseen_partner"].endswith("slow.npz")
    assert avatar.summary["n_sessions"] == 40 and avatar.summary["seed"] == 0
    assert isinstance(avatar.generator, StrokeGenerator)  # the default kind moves the avatar
    assert avatar.summary["generator"] == "strokes" and "n_symbols" not in avatar.summary
    for role in ("follower", "leader"):
        assert set(avatar.summary["roles"][role]) >= {"emd_to_person", "unseen_cv_difference"}
    card = built.with_suffix(".html").read_text()
    assert "Avatar of P01" in card and "Table I" in card and "data:image/png;base64" in card
    strokes = avatar.generator.training_summary_["n_strokes"]
    assert f"stroke generator was fitted on 3 trials ({strokes} strokes)" in card


@pytest.mark.long
def test_the_session_role_picks_the_player(built: Path) -> None:
    follower, leader = load_player(str(built), "follower"), load_player(str(built), "leader")
    assert isinstance(follower, CyberPlayer) and follower.training_["role"] == "follower"
    assert isinstance(leader, CyberPlayer) and leader.training_["role"] == "leader"
    assert isinstance(load_player(str(built), "joint"), VirtualTrainer)


@pytest.mark.long
def test_the_avatar_plays_in_simulate(built: Path, tmp_path: Path) -> None:
    out = tmp_path / "session"
    status = main(["simulate", "--leader", "bundled:fast", "--follower", str(built),
                   "--duration", "5", "--seed", "2", "--out", str(out)])  # fmt: skip
    assert status == 0
    result = json.loads((out / "metrics.json").read_text())
    assert str(built) in json.dumps(result["specs"]) and np.isfinite(result["metrics"]["rmse"])
    assert np.isfinite(result["metrics"]["emd_target_1"])


@pytest.mark.long
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
        (["--sessions", "0"], "give a whole number in [1, "),
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


@pytest.mark.long
def test_live_play_takes_the_avatar_in_every_mode(built: Path) -> None:
    factory = make_avatar_factory(str(built))
    assert factory("avatar_follows").training_["role"] == "follower"  # type: ignore[attr-defined]
    assert factory("avatar_leads").training_["role"] == "leader"  # type: ignore[attr-defined]
    assert isinstance(factory("joint"), VirtualTrainer)


@pytest.mark.long
def test_a_deep_avatar_is_built_saved_and_played(built: Path, tmp_path: Path) -> None:
    folder = built.parent
    out = tmp_path / "P01-deep.npz"
    status = main(["avatar", "create", str(folder / "trials"), "--name", "P01", "--partners",
                   f"{folder / 'fast.npz'},{folder / 'slow.npz'}", "--agent", "dqn",
                   "--sessions", "3", "--jobs", "1", "--holdout", "1",
                   "--out", str(out)])  # fmt: skip
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


@pytest.fixture(scope="module")
def proved(built: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The person's avatar also checked against a session they played with a partner, and
    against one trial held out of its own fitting (``--holdout 1``).

    The dyad: the fast partner leads, the person follows as a virtual trainer driven by their
    held-out trial (trial1 of three).
    """
    folder = built.parent
    dyad = tmp_path_factory.mktemp("dyad")
    status = main(["simulate", "--leader", str(folder / "fast.npz"), "--follower",
                   f"vt:{folder / 'trials' / 'trial1.csv'}", "--duration", "20", "--seed", "5",
                   "--out", str(dyad)])  # fmt: skip
    assert status == 0
    label = json.loads((dyad / "session.json").read_text())["labels"][1]
    out = folder / "P01-proved.npz"
    status = main(["avatar", "create", str(folder / "trials"), "--name", "P01", "--partners",
                   f"{folder / 'fast.npz'},{folder / 'slow.npz'}", "--sessions", "40",
                   "--jobs", "1", "--holdout", "1", "--with-partner", str(dyad / "session.parquet"),
                   "--person-label", label, "--out", str(out)])  # fmt: skip
    assert status == 0
    return out, dyad


def ims_emd(a: np.ndarray, b: np.ndarray) -> float:
    """EMD between two velocity series' IMS by scipy (the toolkit's normalised bins)."""
    from scipy.stats import wasserstein_distance

    from mirror_avatar.signatures.signature import DEFAULT_BINS, compute_ims

    centres = DEFAULT_BINS.centres
    span = centres[-1] - centres[0]
    return wasserstein_distance(centres, centres, compute_ims(a), compute_ims(b)) / span


@pytest.mark.long
def test_the_card_checks_the_avatar_against_each_trial_held_out(built: Path) -> None:
    """Three trials: the avatar is fitted on all, and each is held out in turn from an avatar
    built without it, in every role."""
    from mirror_avatar.files.trial_files import read_trial

    avatar = load_avatar(built)
    assert avatar.generator.training_summary_["labels"] == ["trial0", "trial1", "trial2"]
    held = avatar.summary["proof"]["held_out"]
    assert held["folds"] == [["trial0"], ["trial1"], ["trial2"]]
    trials = [read_trial(built.parent / "trials" / f"trial{k}.csv") for k in range(3)]
    velocities = [t.resampled().velocity() for t in trials]
    own = [ims_emd(velocities[i], velocities[j]) for i, j in ((0, 1), (0, 2), (1, 2))]
    np.testing.assert_allclose(held["own_emd_range"], np.percentile(own, [5, 95]), rtol=1e-6)
    hi = held["own_emd_range"][1]
    assert list(held["roles"]) == ["follower", "leader", "group member"]
    for result in held["roles"].values():
        assert result["flagged"] == (result["emd_to_held_out"] > hi)
        assert result["ratio_to_own"] == pytest.approx(result["emd_to_held_out"] / np.median(own))
    verdict = avatar.summary["verdict"]
    assert verdict.startswith("The avatar moves") and f"95th percentile {hi:.4f}" in verdict
    assert "leave-one-out over 3 trials" in verdict and "role and partner pairs" in verdict
    card = built.with_suffix(".html").read_text()
    assert verdict.replace("'", "&#39;") in card
    assert "P01 against the avatar (positions)" in card


@pytest.mark.long
def test_the_avatar_replays_the_persons_partner(proved: tuple[Path, Path]) -> None:
    """The person's CV, RMS and lag are the recorded session's; the avatar meets the same track."""
    from mirror_avatar.experiments.avatar_proof import find_person, replay_partner

    out, dyad = proved
    avatar = load_avatar(out)
    assert avatar.generator.training_summary_["labels"] == ["trial0", "trial2"]
    held = avatar.summary["proof"]["held_out"]
    assert held["folds"] == [["trial1"]] and held["scheme"] == "1 of 3 trials held out of fitting"
    recorded = json.loads((dyad / "metrics.json").read_text())["metrics"]
    sessions = avatar.summary["proof"]["partners"]["sessions"]
    person = next(row for row in sessions if row["player"] == "person")
    assert person["cv"] == pytest.approx(recorded["phase_locking"])
    assert person["rms"] == pytest.approx(recorded["rmse"])
    assert person["lag"] == pytest.approx(recorded["time_lag"])  # the partner is player 0
    avatar_row = next(row for row in sessions if row["player"] == "avatar")
    assert 0 < avatar_row["cv"] <= 1 and avatar_row["rms"] > 0
    session = load_session(dyad / "session.parquet")
    played = replay_partner(avatar, find_person("d", session, session.labels[1]), 2, seed=0)
    for replay in played:
        np.testing.assert_allclose(replay.positions[0], session.positions[0], atol=1e-12)
        assert replay.roles == ("leader", "follower")
    assert isinstance(avatar.player("follower"), CyberPlayer)
    verdict = avatar.summary["verdict"]
    assert f"CV {avatar_row['cv']:.2f} (person {person['cv']:.2f})" in verdict
    card = out.with_suffix(".html").read_text()
    assert "against their partner&#39;s recorded track" in card


@pytest.mark.long
@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--holdout", "3"], "3 held-out trials of 3: keep at least one to fit"),
        (["--holdout", "-1"], "give a whole number in [0, 1000]"),
        (["--with-partner", "SESSION", "--person-label", "nobody"], "no single player labelled"),
    ],
)
def test_bad_proof_options_are_one_line(built: Path, tmp_path, capsys, extra, message) -> None:
    folder = built.parent
    extra = [str(folder / "dyad.csv") if a == "SESSION" else a for a in extra]
    first, second = load_zhai2017()[:2]
    play([RecordedPlayer(first), RecordedPlayer(second)], 10.0, seed=0).save_csv(
        folder / "dyad.csv"
    )
    arguments = ["avatar", "create", str(folder / "trials"), "--name", "P", "--partners",
                 f"{folder / 'fast.npz'},{folder / 'slow.npz'}", "--out",
                 str(tmp_path / "a.npz"), *extra]  # fmt: skip
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and message in error
    assert not (tmp_path / "a.npz").exists()


@pytest.mark.long
@pytest.mark.parametrize(
    ("leaders", "plays", "kind"),
    [([], "avatar P01 (follower policy)", "CyberPlayer"),
     (["--leader", "2"], "avatar P01 (leader policy)", "CyberPlayer")],
)  # fmt: skip
def test_an_avatar_in_a_group_plays_its_policy_and_says_so(
    built: Path, tmp_path: Path, leaders: list[str], plays: str, kind: str
) -> None:
    """A group member is the avatar's follower policy, its leader policy as group leader."""
    out = tmp_path / "group"
    status = main(["group", "simulate", "--player", "bundled:fast", "--player", "bundled:slow",
                   "--player", str(built), *leaders, "--duration", "5", "--seed", "1",
                   "--out", str(out)])  # fmt: skip
    assert status == 0
    sidecar = json.loads((out / "session.json").read_text())
    assert sidecar["labels"][2] == plays
    described = sidecar["metadata"]["players"][2]
    assert described["class"] == kind and described["label"] == plays
    session = load_session(out / "session.parquet")
    assert session.labels[2] == plays and np.ptp(session.positions[2]) > 0
    role = "leader" if leaders else "follower"
    policy = load_avatar(built).players[role]
    assert np.isfinite(session.controls[2, :-1]).all()
    player = load_player(str(built), "group_leader" if leaders else "group")
    assert isinstance(player, CyberPlayer) and player.training_["role"] == role
    np.testing.assert_array_equal(player.q_table_, policy.q_table_)


@pytest.mark.long
def test_joint_improvisation_plays_the_virtual_trainer_and_says_so(
    built: Path, tmp_path: Path
) -> None:
    out = tmp_path / "joint"
    status = main(["simulate", "--leader", "bundled:fast", "--follower", str(built), "--joint",
                   "--duration", "5", "--seed", "2", "--out", str(out)])  # fmt: skip
    assert status == 0
    sidecar = json.loads((out / "session.json").read_text())
    assert sidecar["labels"][1] == "avatar P01 (virtual trainer)"
    assert sidecar["metadata"]["players"][1]["class"] == "VirtualTrainer"


@pytest.mark.long
def test_each_call_gives_a_player_of_its_own(built: Path) -> None:
    avatar = load_avatar(built)
    first, second = avatar.player("group"), avatar.player("group")
    assert first is not second and first.label == second.label == "avatar P01 (follower policy)"
    assert avatar.players["follower"].label != first.label  # the file's player is untouched


@pytest.mark.long
def test_an_avatar_without_held_out_trials_says_it_is_not_checked(built: Path) -> None:
    folder = built.parent
    out = folder / "P01-unchecked.npz"
    status = main(["avatar", "create", str(folder / "trials"), "--name", "P01", "--partners",
                   f"{folder / 'fast.npz'},{folder / 'slow.npz'}", "--sessions", "2",
                   "--jobs", "1", "--holdout", "0", "--out", str(out)])  # fmt: skip
    assert status == 0
    avatar = load_avatar(out)
    assert avatar.summary["proof"]["held_out"] is None
    verdict = avatar.summary["verdict"]
    assert verdict.startswith("The avatar is not checked against the person: no trial was held")
    card = out.with_suffix(".html").read_text()
    assert "<p>The avatar is not checked against the person" in card  # its text says so first
    assert "No solo trial was held out of fitting." in card
