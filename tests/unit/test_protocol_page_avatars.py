"""Where a protocol's avatar runs: ``runs = "browser"`` checked when the protocol is read."""

from __future__ import annotations

from pathlib import Path

import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.testing import seeded_avatar

RECORDING = Path(__file__).parents[2] / "examples" / "protocols" / "turing" / "slow-1.csv"

PROTOCOL = """
title = "where the avatar runs"
seed = 1

[[blocks]]
name = "main"

[[blocks.conditions]]
name = "follow"
game = "{game}"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "A1", kind = "{kind}", spec = "{spec}", runs = "browser" }},
  {extra}
]
leaders = ["P1"]
{more}
"""


def protocol(tmp_path: Path, **values: str) -> Path:
    """A protocol of one condition whose avatar A1 runs in the browser, written to a file."""
    fields = {"game": "leader_follower", "kind": "avatar", "spec": str(RECORDING),
              "extra": "", "more": ""} | values  # fmt: skip
    path = tmp_path / "study.toml"
    path.write_text(PROTOCOL.format(**fields))
    return path


def refusal(path: Path) -> str:
    with pytest.raises(InputError) as error:
        load_protocol(path)
    text = str(error.value)
    assert "\n" not in text and text.startswith(f"{path}: blocks[0].conditions[0]"), text
    return text


@pytest.mark.parametrize("kind", ["avatar", "person-or-avatar"])
def test_a_kind_the_browser_cannot_run_is_refused_naming_the_player_and_the_fix(tmp_path, kind):
    path = protocol(tmp_path, spec="bundled:slow", kind=kind)
    text = refusal(path)
    assert ".players[1].runs: condition 'follow': " in text
    assert "cannot be stepped in the browser" in text and 'set runs = "server"' in text


def test_an_avatar_in_the_browser_beside_two_people_is_refused(tmp_path):
    path = protocol(tmp_path, game="group", extra='{ label = "P2", kind = "person" },')
    text = refusal(path)
    assert ".players: A1 runs in the browser, which needs a dyad of one person" in text
    assert "set runs = 'server'" in text


def test_a_perturbation_of_an_avatar_in_the_browser_is_refused(tmp_path):
    seeded_avatar("tabular", tmp_path)
    more = 'perturb = [{ at = 1, player = "A1", set = "leader" }]'
    text = refusal(protocol(tmp_path, spec=str(tmp_path / "tabular.npz"), more=more))
    assert ".perturb: condition 'follow': A1 runs in the browser" in text


@pytest.mark.parametrize(
    "more",
    ["delay = 0.2", "occlude = [[1, 2]]", 'partner_view = "predicted"', "delay_jitter = 0.05"],
)
def test_a_partner_delayed_or_hidden_is_refused_beside_an_avatar_in_the_browser(tmp_path, more):
    key = more.split()[0]
    text = refusal(protocol(tmp_path, more=more))
    assert f".{key}: A1 runs in the browser, whose page draws it as it steps it" in text


def test_a_person_has_no_runs(tmp_path):
    path = protocol(tmp_path)
    path.write_text(
        path.read_text().replace('kind = "person" }', 'kind = "person", runs = "browser" }')
    )
    assert ".players[0].runs: a person's page is where a person plays (remove it)" in refusal(path)


def test_a_recording_in_the_browser_is_read_with_a_warning_that_the_page_knows(tmp_path):
    loaded = load_protocol(protocol(tmp_path))
    (slot,) = [s for s in loaded.blocks[0].conditions[0].with_avatars().slots if s.label == "A1"]
    assert slot.runs == "browser"
    assert any("A1 runs in the browser" in warning for warning in loaded.warnings)
