"""Perturbations of avatars: a successor taking over a trial, what each spec can change, and
every refusal at load time."""

from __future__ import annotations

import copy
import tomllib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.lab.design.perturbation import changeable, successor
from mirror_avatar.lab.design.protocol import parse_protocol
from mirror_avatar.lab.running.study import ParticipantRun
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.players import RecordedPlayer
from mirror_avatar.players.base import Observation, Player
from mirror_avatar.specs import load_player, model_partner
from mirror_avatar.training.avatar import Avatar

EXAMPLE = Path(__file__).parents[2] / "examples" / "protocol.toml"


def partner(k: int) -> Observation:
    t = np.array([k, max(k - 1, 0)]) * 0.03
    x = 0.3 * np.sin(np.pi * t)
    return Observation.of_partner(k, x[0], 0.3 * np.pi * np.cos(np.pi * t[0]), x[1])


def trajectory(first: Player, then: Player | None, at: int, steps: int = 80) -> np.ndarray:
    player, states = first, [first.reset(seed=9)]
    if then is not None:
        then.reset(seed=9)
    for k in range(steps):
        if then is not None and k == at:
            then.take_over(player)
            player = then
        states.append(player.step(partner(k)))
    return np.array(states)


def cyber_player() -> CyberPlayer:
    player = CyberPlayer()
    player.initialise_q(3, 1.0)
    return player


FACTORIES: dict[str, Callable[[], Player]] = {
    "virtual trainer": lambda: load_player("bundled:slow", "follower"),
    "cyber player": cyber_player,
    **{
        name: (lambda name=name: model_partner(name))
        for name in ("adaptive", "rpc", "hkb", "excitator", "kuramoto")
    },
}


@pytest.mark.parametrize("kind", FACTORIES)
def test_a_successor_changing_nothing_continues_the_trial_bit_for_bit(kind):
    make = FACTORIES[kind]
    alone = trajectory(make(), None, 0)
    handed = trajectory(make(), make(), at=37)
    np.testing.assert_array_equal(handed, alone)


def test_a_changed_successor_parts_at_the_next_sample():
    alone = trajectory(model_partner("hkb"), None, 0)
    changed = trajectory(model_partner("hkb"), successor("hkb", "follower", {"a": 3.0}), at=37)
    np.testing.assert_array_equal(changed[:38], alone[:38])
    assert np.all(changed[38:, 0] != alone[38:, 0])


def test_a_player_takes_over_only_its_own_kind():
    with pytest.raises(InputError, match="cannot take over the trial of KuramotoPlayer"):
        model_partner("hkb").take_over(model_partner("kuramoto"))
    recorded = RecordedPlayer(load_zhai2017()[0])
    with pytest.raises(InputError, match="cannot take over"):
        recorded.take_over(RecordedPlayer(load_zhai2017()[1]))


def test_what_each_spec_can_change(tmp_path):
    trainer = changeable("bundled:slow")
    assert "leader" in trainer.roles and "period" not in trainer.parameters
    assert trainer.parameters["theta_p"] == (0.0, 1.0)
    adaptive = changeable("adaptive:cp=20")
    assert "leader" in adaptive.roles and "a0" not in adaptive.parameters
    assert "cp" in adaptive.parameters
    assert changeable("kuramoto").roles == () and "phase" not in changeable("kuramoto").parameters
    generator = IMSGenerator(n_symbols=8, random_state=0).fit(load_zhai2017()[:2])
    generator.save(tmp_path / "generator.npz")
    assert changeable(str(tmp_path / "generator.npz")) == trainer
    players = {}
    for role in ("follower", "leader"):
        players[role] = cyber_player()
        players[role].training_ = {"role": role}
    Avatar("P9", generator, players).save(tmp_path / "avatar.npz")
    avatar = str(tmp_path / "avatar.npz")
    assert changeable(avatar).roles == ("follower", "leader", "group", "group_leader")
    assert changeable(avatar).parameters == {}
    assert successor(avatar, "leader", {}).label == "avatar P9 (leader policy)"
    players["follower"].save(tmp_path / "cyber.npz")
    assert changeable(str(tmp_path / "cyber.npz")) == changeable("trial.csv")
    assert changeable("trial.csv").roles == () and changeable("trial.csv").parameters == {}


def with_perturb(entries: list, condition: int = 0, spec: str | None = None) -> dict:
    data = copy.deepcopy(tomllib.loads(EXAMPLE.read_text()))
    target = data["blocks"][1]["conditions"][condition]
    target["perturb"] = entries
    if spec is not None:
        target["players"][1]["spec"] = spec
    return data


def test_perturbations_are_read_in_order_of_time():
    entries = [
        {"at": 20, "player": "A1", "set": "theta_p=0.5, omega=0.3"},
        {"at": 10.0, "player": "A1", "set": "follower"},
    ]
    condition = parse_protocol(with_perturb(entries), "p.toml").blocks[1].conditions[0]
    assert [(p.sample, p.change) for p in condition.perturb] == [
        (333, "role=follower"),
        (667, "theta_p=0.5,omega=0.3"),
    ]
    joint = with_perturb([{"at": 5, "player": "P2", "set": "leader"}], condition=1)
    assert parse_protocol(joint, "p.toml").blocks[1].conditions[1].perturb[0].player == "P2"


WHERE = "p.toml: blocks[1].conditions[0].perturb"


@pytest.mark.parametrize(
    ("entries", "spec", "message"),
    [
        ({"at": 5}, None, "perturb: must be a list of 1 to 20 entries"),
        ([{"at": 5, "player": "Z", "set": "leader"}], None, "[0].player: 'Z' plays no part"),
        ([{"at": 5, "player": "P1", "set": "leader"}], None, "P1 is a person, not an avatar"),
        ([{"at": 30, "player": "A1", "set": "leader"}], None, "[0].at: must be seconds within"),
        ([{"at": 0, "player": "A1", "set": "leader"}], None, "[0].at: must be seconds within"),
        ([{"at": True, "player": "A1", "set": "leader"}], None, "[0].at: must be seconds"),
        ([{"at": 5, "player": "A1", "set": ""}], None, "[0].set: must name a role or"),
        ([{"at": 5, "player": "A1", "set": "boss"}], None, "cannot take the role 'boss'"),
        ([{"at": 5, "player": "A1", "set": "cp=3"}], None, "has no parameter 'cp' to change"),
        ([{"at": 5, "player": "A1", "set": "theta_p=x"}], None, "'theta_p=x' is not a new"),
        ([{"at": 5, "player": "A1", "set": "eta=0"}], None, "eta must lie between 1e-08"),
        ([{"at": 5, "player": "A1", "set": "theta_v=0.95"}], None, "theta_p + theta_v must not"),
        ([{"at": 5, "player": "A1", "set": "leader", "to": 1}], None, "[0].to: unknown key"),
        ([{"at": 5, "player": "A1", "set": "leader"}], "hkb", "hkb cannot take the role"),
        ([{"at": 5, "player": "A1", "set": "phase=1"}], "kuramoto", "no parameter 'phase'"),
        ([{"at": 5, "player": "A1", "set": "a=1"}], "trial.csv", "it takes none"),
        ([{"at": 5, "player": "A1", "set": "leader"}], "missing.npz", "cannot be read"),
        (
            [
                {"at": 5, "player": "A1", "set": "leader"},
                {"at": 5.01, "player": "A1", "set": "eta=1"},
            ],
            None,
            "A1 is already perturbed at that sample",
        ),
    ],
)
def test_each_perturbation_mistake_is_refused_with_one_line(entries, spec, message):
    with pytest.raises(InputError) as error:
        parse_protocol(with_perturb(entries, spec=spec), "p.toml")
    text = str(error.value)
    assert text.startswith(WHERE) and message in text and "\n" not in text, text


def test_a_virtual_trainers_successor_takes_the_role_and_the_values():
    changed = successor("bundled:slow", "follower", {"theta_p": 0.3, "omega": 0.5})
    assert (changed.params.theta_p, changed.params.omega) == (0.3, 0.5)
    assert changed.params.alpha == load_player("bundled:slow", "follower").params.alpha
    leading = successor("adaptive:cp=20", "leader", {"leader_cp": 7.0})
    assert (leading.cp, leading.options["cp"]) == (7.0, 20.0)


def test_a_person_filling_the_slot_is_not_perturbed(tmp_path):
    data = with_perturb([{"at": 5, "player": "P2", "set": "leader"}], condition=1)
    protocol = parse_protocol(data, str(tmp_path / "p.toml"))
    found = {}
    for participant in (0, 1):  # a pair: one meets the person, the other the avatar
        run = ParticipantRun(protocol, participant)
        n = next(run.first_trials[i] for i, s in enumerate(run.steps) if s.name == "joint")
        run.enter(n, again=True)
        found[run.steps[run.step].persons["P2"]] = run.perturbations()
    assert found[True] == []
    ((index, perturbation),) = found[False]
    assert (index, perturbation.change) == (1, "role=leader")
