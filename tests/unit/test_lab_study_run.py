"""A participant's run of a protocol: trials numbered across conditions, where it is, which
questions follow which trial, and resuming from its folder."""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.runner import LabSession
from mirror_avatar.lab.running.study import ParticipantRun, study_folder

EXAMPLE = Path(__file__).parents[2] / "examples" / "protocol.toml"


def _session(tmp_path: Path, participant: int = 0, seed: int | None = None) -> LabSession:
    protocol = load_protocol(EXAMPLE)
    if seed is not None:
        protocol = replace(protocol, seed=seed)
    folder = tmp_path / study_folder(protocol, participant)
    return LabSession(folder.name, ParticipantRun(protocol, participant), folder, time.monotonic)


def _run(session: LabSession) -> ParticipantRun:
    assert isinstance(session.schedule, ParticipantRun)
    return session.schedule


def test_trials_are_numbered_across_the_participants_conditions(tmp_path):
    session = _session(tmp_path, participant=2)
    names = [step.name for step in _run(session).steps]
    assert session.directory.name == "protocol-p002"
    assert session.total_trials == 1 + 2 + 2 + 2 + 2
    assert _run(session).where(1) == "block 1 of 2, condition 'solo', trial 1 of 1"
    assert _run(session).where(2) == f"block 2 of 2, condition '{names[1]}', trial 1 of 2"
    assert _run(session).where(9) == f"block 2 of 2, condition '{names[-1]}', trial 2 of 2"
    study = json.loads((session.directory / "study.json").read_text())
    assert [c["condition"] for c in study["order"]] == names
    assert [c["trials"] for c in study["order"]] == [[1], [2, 3], [4, 5], [6, 7], [8, 9]]
    assert study["seed"] == 20261125 and study["participant"] == 2


def test_block_questions_follow_the_last_trial_of_the_block(tmp_path):
    session = _session(tmp_path)
    assert _run(session).questions_after(1) == {"trial": [], "block": []}
    last = _run(session).questions_after(session.total_trials)
    assert last["block"] == ["remarks"]
    assert all(
        _run(session).questions_after(n)["block"] == [] for n in range(1, session.total_trials)
    )


def test_a_folder_resumes_at_the_first_trial_with_no_files(tmp_path):
    session = _session(tmp_path)
    for n in (1, 2, 3):
        (session.directory / f"trial-{n:02d}_session.csv").write_text("t\n")
    resumed = _session(tmp_path)
    assert resumed.next_trial == 4
    assert resumed.plan == _run(resumed).plans[_run(resumed)._step_of(4)]
    assert any("resumed at trial 4 of 9" in event for event in resumed.events)


def test_a_folder_of_another_seed_or_no_study_is_refused(tmp_path):
    _session(tmp_path)
    with pytest.raises(InputError, match=r"study\.json: recorded with another seed"):
        _session(tmp_path, seed=5)
    stray = tmp_path / "protocol-p001"
    stray.mkdir()
    with pytest.raises(InputError, match=r"study\.json: this folder holds no readable study"):
        _session(tmp_path, participant=1)


def test_balanced_partner_draws_are_recorded_and_resumed(tmp_path):
    kinds = []
    for participant in range(4):
        session = _session(tmp_path, participant)
        study = json.loads((session.directory / "study.json").read_text())
        joint = next(c for c in study["order"] if c["condition"] == "joint")
        kinds.append(joint["players"]["P2"])
        drawn = next(s.persons["P2"] for s in _run(session).steps if s.name == "joint")
        assert kinds[-1] == ("human" if drawn else "avatar")
        resumed = _session(tmp_path, participant)
        assert _run(resumed).describe(resumed.id, resumed.created_utc)["order"] == study["order"]
    assert kinds[0] != kinds[1] and kinds[2] != kinds[3]


@pytest.mark.parametrize("participant", [0, 1])
def test_the_outlet_channels_are_every_label_of_the_run(tmp_path, participant):
    session = _session(tmp_path, participant)
    labels, roles, kinds = _run(session).channels()
    assert labels[:2] == ["P1", "P2"] and sorted(labels[2:]) == ["A1", "A2"]
    kind = dict(zip(labels, kinds, strict=True))
    assert (kind["P1"], kind["A1"], kind["A2"]) == ("human", "avatar", "avatar")
    meets_avatar = any(step.persons.get("P2") is False for step in _run(session).steps)
    assert kind["P2"] == ("human/avatar" if meets_avatar else "human")
    assert roles[0].split("/")[0] == "solo" and "leader" in roles[0].split("/")


def _earlier_draws(protocol, participant: int) -> list[tuple[str, dict[str, str]]]:
    """The partners block's order and kinds as drawn before partner kinds were balanced over
    positions (literal-tagged streams; kinds drawn per pair of participants and condition)."""
    from mirror_avatar.lab.design.order import williams_square

    block = protocol.blocks[1]
    symbols = np.random.default_rng([protocol.seed, 3, 1]).permutation(4)
    order = [int(symbols[s]) for s in williams_square(4)[participant % 4]]
    pair, second = divmod(participant, 2)
    drawn = []
    for c in order:
        condition = block.conditions[c]
        players = {}
        for k, player in enumerate(condition.players):
            kind = "avatar" if player.kind == "avatar" else "human"
            if player.kind == "person-or-avatar":
                rng = np.random.default_rng([protocol.seed, 4, pair, 1, c, k])
                kind = "human" if (rng.random() < 0.5) != bool(second) else "avatar"
            players[player.label] = kind
        drawn.append((condition.name, players))
    return drawn


@pytest.mark.parametrize("participant", range(4))
def test_a_run_recorded_with_the_earlier_draws_refuses_to_resume_in_one_line(tmp_path, participant):
    session = _session(tmp_path, participant)
    path = session.directory / "study.json"
    study = json.loads(path.read_text())
    earlier = [
        ("solo", study["order"][0]["players"]),
        *_earlier_draws(_run(session).protocol, participant),
    ]
    assert earlier != [(c["condition"], c["players"]) for c in study["order"]]
    for recorded, (name, players) in zip(study["order"], earlier, strict=True):
        recorded["condition"], recorded["players"] = name, players
    path.write_text(json.dumps(study))
    with pytest.raises(InputError) as refused:
        _session(tmp_path, participant)
    assert str(refused.value) == f"{path}: recorded with another order (use another --out folder)"
