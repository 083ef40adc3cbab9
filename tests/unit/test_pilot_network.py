"""A pilot's emulated internets: one before everyone, one per person
(`mirror_avatar.lab.running.pilot_network`)."""

from __future__ import annotations

import json

import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.lab.running.pilot_network import (
    EVERYONE,
    describe,
    emulated_internets,
    network_files,
    parse_networks,
)
from mirror_avatar.remote.network import parse_network

PEOPLE = ("P1", "P2", "P3")


@pytest.mark.parametrize(
    ("values", "expected"),
    [
        (["80+-25"], {EVERYONE: "80+-25"}),
        (["up=120+-40,down=40+-15"], {EVERYONE: "up=120+-40,down=40+-15"}),
        (["80+-25,stall=30:1"], {EVERYONE: "80+-25,stall=30:1"}),
        (["P1=20+-5", "P2=150+-40"], {"P1": "20+-5", "P2": "150+-40"}),
        (["P2=up=120+-40,down=40", "none"], {"P2": "up=120+-40,down=40", EVERYONE: "none"}),
        ([], {}),
    ],
)
def test_a_network_is_everyone_s_or_a_person_s(values, expected):
    networks = parse_networks(values, PEOPLE)
    assert networks == {label: parse_network(spec) for label, spec in expected.items()}


@pytest.mark.parametrize(
    ("values", "problem"),
    [
        (["P9=20"], "'P9=20': P9 is no person of the protocol (its people: P1, P2, P3)"),
        (["P1=20", "P1=30"], "'P1=30': a second network for person P1"),
        (["80", "none"], "'none': a second network for every person"),
        (["P1=fast"], "'fast' is not a delay"),
        (["up=80"], "'up=80': no down delay"),
    ],
)
def test_a_bad_network_is_refused_naming_the_option(values, problem):
    with pytest.raises(InputError) as refused:
        parse_networks(values, PEOPLE)
    line = str(refused.value)
    assert line.startswith("--network: ") and problem in line and "\n" not in line, line


def test_each_network_writes_its_own_truth_and_says_where():
    networks = parse_networks(["P1=20+-5", "80"], PEOPLE)
    assert network_files(networks) == [
        "pilot-network-P1.csv", "pilot-network-P1.json", "pilot-network.csv", "pilot-network.json"
    ]  # fmt: skip
    assert describe(networks) == (
        "networks P1 20+-5 (truth in pilot-network-P1.csv), everyone else 80 (truth in "
        "pilot-network.csv)"
    )
    assert describe(parse_networks(["80"], PEOPLE)) == "network 80, its truth in pilot-network.csv"


def test_a_person_joins_through_their_own_network_else_everyone_s_else_directly(tmp_path):
    base = "http://127.0.0.1:9"  # never reached: no page connects
    networks = parse_networks(["P2=150+-10", "20"], PEOPLE)
    with emulated_internets(networks, base, tmp_path, 7, PEOPLE) as join_at:
        assert join_at["P1"] == join_at["P3"] != join_at["P2"]
        assert base not in join_at.values()
    facts = {
        name: json.loads((tmp_path / name).read_text())
        for name in network_files(networks)
        if name.endswith(".json")
    }
    assert {name: fact["proxy"] for name, fact in facts.items()} == {
        "pilot-network-P2.json": join_at["P2"], "pilot-network.json": join_at["P1"]
    }  # fmt: skip
    assert {name: fact["seed"] for name, fact in facts.items()} == {
        "pilot-network-P2.json": int(spawn_seeds(7, 3)[1]), "pilot-network.json": 7
    }  # fmt: skip
    alone = parse_networks(["P1=20"], PEOPLE)
    with emulated_internets(alone, base, tmp_path, 7, PEOPLE) as join_at:
        assert join_at["P2"] == join_at["P3"] == base != join_at["P1"]
