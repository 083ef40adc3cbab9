"""A protocol's avatars resolved and dry-run when it is read; a run planned too long warned of."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import load_protocol, parse_protocol
from mirror_avatar.lab.design.protocol_store import store_protocol

EXAMPLE = Path(__file__).parents[2] / "examples" / "protocol.toml"

DYAD = """
title = "one dyad"
seed = 1

[[blocks]]
name = "main"

[[blocks.conditions]]
name = "hard"
game = "leader_follower"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "A1", kind = "{kind}", spec = "{spec}" }},
]
leaders = ["P1"]
"""

DIVERGES = "hkb:a=1000,b=-1000,alpha=0,beta=0,gamma=-100,omega=100"


@pytest.mark.parametrize(
    ("spec", "problem"),
    [
        ("adaptive:cp=nan", "adaptive:cp=nan: cp must be a number in ASCII decimals"),
        ("kuramoto:k=inf", "kuramoto:k=inf: unknown parameter 'k'"),
        ("/etc/passwd", "/etc/passwd: unknown extension"),
        ("rpc:omega_low=1,omega_high=0.5", "omega_low 1 must be below omega_high 0.5"),
        (DIVERGES, f"{DIVERGES}: diverges: 0.03 s into a dry run"),
    ],
)
@pytest.mark.parametrize("kind", ["avatar", "person-or-avatar"])
def test_every_avatar_spec_is_built_when_the_protocol_is_read(tmp_path, spec, problem, kind):
    path = tmp_path / "study.toml"
    path.write_text(DYAD.format(spec=spec, kind=kind))
    loads = {str(path): lambda: load_protocol(path), "s.toml": lambda: store_protocol(
        tmp_path / "out", "s.toml", path.read_text())}  # fmt: skip
    for source, load in loads.items():
        with pytest.raises(InputError) as error:
            load()
        text = str(error.value)
        where = f"{source}: blocks[0].conditions[0].players[1].spec: condition 'hard': "
        assert text.startswith(where) and problem in text and "\n" not in text, text
    assert not (tmp_path / "out").exists()


def test_a_perturbation_that_makes_an_avatar_diverge_is_refused():
    data = copy.deepcopy(tomllib.loads(EXAMPLE.read_text()))
    follow = data["blocks"][1]["conditions"][0]
    follow["players"][1]["spec"] = "hkb"
    follow["perturb"] = [{"at": 5.0, "player": "A1", "set": "a=1000,b=-1000,alpha=0,beta=0"}]
    with pytest.raises(InputError) as error:
        parse_protocol(data, "p.toml")
    assert str(error.value).startswith(
        "p.toml: blocks[1].conditions[0].perturb: condition 'follow': hkb with "
        "a=1000,b=-1000,alpha=0,beta=0 at 5 s: diverges: "
    ), error.value


def test_a_run_planned_over_four_hours_is_read_with_a_warning_saying_how_long():
    assert load_protocol(EXAMPLE).warnings == ()
    conditions = [
        {"name": f"c{b}-{c}", "game": "solo", "players": [{"label": "P1", "kind": "person"}],
         "trials": 100, "duration": 600, "pause": 600}
        for b in range(20)
        for c in range(20)
    ]  # fmt: skip
    blocks = [{"name": f"b{b}", "conditions": conditions[20 * b : 20 * b + 20]} for b in range(20)]
    protocol = parse_protocol({"seed": 1, "blocks": blocks}, "long.toml")
    (warning,) = protocol.warnings  # 400 conditions of 100 x 600 s and 99 x 600 s: 47 760 000 s
    assert warning == (
        "long.toml: a participant's run is planned to last 13266.7 h (552.8 days) of trials and "
        "pauses, over 4 h: check the trials, durations and pauses"
    )


@pytest.mark.parametrize("raw", ["1_0", "\u0660.5", "nan"])
def test_a_perturbations_values_are_plain_ascii_decimals(raw):
    data = copy.deepcopy(tomllib.loads(EXAMPLE.read_text()))
    data["blocks"][1]["conditions"][0]["perturb"] = [
        {"at": 5.0, "player": "A1", "set": f"theta_p={raw}"}
    ]
    with pytest.raises(InputError, match=rf"perturb\[0\]\.set: 'theta_p={raw}' is not a new"):
        parse_protocol(data, "p.toml")
