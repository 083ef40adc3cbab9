"""Protocols chosen under names in any script keep their letters, safely: composed (NFC), no
path separator, dot or control character, within the bytes a file name may have."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from mirror_avatar.lab.design.protocol_store import MAX_NAME_BYTES, protocol_name, store_protocol
from mirror_avatar.lab.running.runner import LabSession
from mirror_avatar.lab.running.study import ParticipantRun, study_folder

EXAMPLE = Path(__file__).parents[2] / "examples" / "protocol.toml"


@pytest.mark.parametrize(
    ("chosen", "name"),
    [
        ("протокол.toml", "протокол"),
        ("études.toml", "études"),
        ("e\u0301tudes.toml", "études"),  # decomposed: composed as NFC
        ("研究 2.toml", "研究-2"),
        ("a/b\\c.toml", "c"),
        ("pilot\u202eswap\x07\x1b.toml", "pilot-swap"),  # bidi override and control characters
        ("..\u2028étude.toml", "étude"),
    ],
)
def test_letters_of_any_script_are_kept_and_nothing_unsafe(chosen, name):
    assert protocol_name(chosen) == name


def test_a_name_of_wide_letters_stays_within_a_file_names_bytes():
    name = protocol_name("\U0001d49c" * 64 + ".toml")  # MATHEMATICAL SCRIPT CAPITAL A, 4 bytes
    assert len(name.encode("utf-8")) <= MAX_NAME_BYTES and set(name) == {"\U0001d49c"}


def test_a_protocol_named_in_cyrillic_is_kept_and_names_its_participants_folders(tmp_path):
    protocol = store_protocol(tmp_path, "протокол.toml", EXAMPLE.read_text())
    assert Path(protocol.source) == tmp_path / "protocols" / "протокол.toml"
    assert study_folder(protocol, 3) == "протокол-p003"
    folder = tmp_path / study_folder(protocol, 3)
    session = LabSession(folder.name, ParticipantRun(protocol, 3), folder, time.monotonic)
    assert (session.directory / "study.json").is_file()
