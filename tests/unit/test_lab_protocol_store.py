"""Protocols loaded from the console: the name kept, the copy and its drawn seed, refusals."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.design.protocol_store import (
    SEED_LINE,
    protocol_name,
    same_protocol,
    store_protocol,
)

EXAMPLE = Path(__file__).parents[2] / "examples" / "protocol.toml"
SEEDED = EXAMPLE.read_text()
UNSEEDED = re.sub(r"(?m)^seed = .*\n", "", SEEDED)


@pytest.mark.parametrize(
    ("chosen", "name"),
    [
        ("study.toml", "study"),
        ("My study (v2).toml", "My-study-v2"),
        ("C:\\Users\\lab\\pilot.toml", "pilot"),
        ("/home/lab/a.b.toml", "a-b"),
        ("étude.toml", "étude"),
        ("x" * 100 + ".toml", "x" * 64),
    ],
)
def test_a_protocol_is_kept_under_its_files_stem_in_safe_characters(chosen, name):
    assert protocol_name(chosen) == name


@pytest.mark.parametrize("chosen", ["", "---.toml", "../..", "\u0301\u0301.toml"])
def test_a_name_without_letters_or_digits_is_refused(chosen):
    with pytest.raises(InputError, match="the file name has no letters or digits"):
        protocol_name(chosen)


def test_a_seeded_protocol_is_kept_as_sent(tmp_path):
    protocol = store_protocol(tmp_path, "study.toml", SEEDED)
    copy = tmp_path / "protocols" / "study.toml"
    assert protocol.source == str(copy) and copy.read_text() == SEEDED
    assert protocol.seed == load_protocol(EXAMPLE).seed


def test_an_unseeded_protocol_keeps_its_drawn_seed_and_reloads_it(tmp_path):
    assert "seed" not in tomllib.loads(UNSEEDED)
    first = store_protocol(tmp_path, "study.toml", UNSEEDED)
    copy = tmp_path / "protocols" / "study.toml"
    assert copy.read_text() == SEED_LINE.format(seed=first.seed) + UNSEEDED
    again = store_protocol(tmp_path, "study.toml", UNSEEDED)
    assert again == first == load_protocol(copy)


def test_another_protocol_never_replaces_a_kept_one(tmp_path):
    store_protocol(tmp_path, "study.toml", UNSEEDED)
    kept = (tmp_path / "protocols" / "study.toml").read_text()
    with pytest.raises(InputError, match="holds another protocol of that name") as refused:
        store_protocol(tmp_path, "study.toml", SEEDED)
    assert refused.value.source == "study.toml"
    assert (tmp_path / "protocols" / "study.toml").read_text() == kept


def test_a_bad_protocol_is_refused_by_the_chosen_files_name_and_nothing_is_kept(tmp_path):
    bad = SEEDED.replace('block_order = "fixed"', 'block_order = "shuffled"')
    with pytest.raises(InputError) as refused:
        store_protocol(tmp_path, "C:\\lab\\pilot.toml", bad)
    assert str(refused.value) == (
        "pilot.toml: block_order: 'shuffled' is not allowed (give one of fixed, random)"
    )
    assert not (tmp_path / "protocols").exists()


@pytest.mark.parametrize(
    ("kept", "text", "same"),
    [
        ("a = 1\n", "a = 1\n", True),
        (SEED_LINE.format(seed=5) + "a = 1\n", "a = 1\n", True),
        ("seed = 5\na = 1\n", "a = 1\n", False),
        (SEED_LINE.format(seed=5) + "a = 2\n", "a = 1\n", False),
        ("a = 1\n", "a = 1\nb = 2\n", False),
    ],
)
def test_a_kept_copy_holds_a_text_as_sent_or_after_its_drawn_seed(kept, text, same):
    assert same_protocol(kept, text) is same
