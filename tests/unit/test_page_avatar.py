"""The server's side of an avatar stepped in its person's page: what a sample records of it,
what it counts missing, the page's messages it takes and refuses."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from mirror_avatar.common.errors import InputError
from mirror_avatar.lab.running.messages import AvatarPosition, parse_participant_message
from mirror_avatar.lab.running.page_avatar import PageAvatar, PageStep
from mirror_avatar.players import RecordedPlayer
from mirror_avatar.realtime.messages import ProtocolError
from mirror_avatar.specs import load_player

RECORDING = Path(__file__).parents[2] / "examples" / "protocols" / "turing" / "slow-1.csv"


@pytest.fixture
def avatar() -> PageAvatar:
    player = load_player(str(RECORDING), "follower")
    assert isinstance(player, RecordedPlayer)
    avatar = PageAvatar(player, "A1", 100)
    avatar.reset(seed=3)
    return avatar


def test_each_sample_records_the_newest_tick_and_counts_a_sample_with_none_newer(avatar):
    start = tuple(avatar.message["start"])
    assert avatar.current_state() == start and not avatar.last_missing  # sample 0: tick 0
    assert avatar.current_state() == start and avatar.last_missing  # nothing reported yet
    for tick in (1, 2, 3):
        avatar.put(PageStep(tick, tick / 10, 1.0, 0.2))
    avatar.put(PageStep(2, 9.0, 9.0, 9.0))  # older than the newest: ignored
    assert avatar.current_state() == (0.3, 1.0) and avatar.tick_fields() == ["3", "0.2", "0"]
    assert avatar.current_state() == (0.3, 1.0) and avatar.tick_fields() == ["3", "0.2", "1"]
    assert avatar.missing == 2 and avatar.ready.is_set()
    assert avatar.tick_columns() == ["tick_A1", "seen_A1", "missing_A1"]


def test_every_tick_reported_is_written_recorded_or_not(avatar, tmp_path):
    for tick in (1, 2):
        avatar.put(PageStep(tick, tick / 10, 1.0, 0.2))
    avatar.write_steps(tmp_path / "page.csv")
    with (tmp_path / "page.csv").open() as file:
        rows = list(csv.DictReader(file))
    assert [row["tick"] for row in rows] == ["0", "1", "2"]
    assert math.isnan(float(rows[0]["seen"])) and float(rows[2]["x"]) == 0.2


def test_a_player_the_page_cannot_step_is_refused_in_one_line():
    with pytest.raises(InputError, match="cannot be stepped in the browser") as error:
        PageAvatar(load_player("bundled:slow", "follower"), "A1", 100)
    assert "\n" not in str(error.value)


def test_the_page_sends_the_avatar_s_state_with_the_person_s_position():
    text = '{"type": "position", "seq": 4, "x": 0.25, "avatar": {"tick": 7, "x": -0.1, "v": 0.5}}'
    message = parse_participant_message(text)
    assert isinstance(message, AvatarPosition)
    assert (message.position.x, message.position.seq) == (0.25, 4)
    assert message.step == PageStep(7, -0.1, 0.5, 0.25)


@pytest.mark.parametrize(
    ("field", "problem"),
    [
        ("[1, 2]", "'avatar' must be an object"),
        ('{"tick": -1, "x": 0, "v": 0}', "'tick' must be a non-negative integer"),
        ('{"tick": 1, "x": 2, "v": 0}', "outside the playing range"),
        ('{"tick": 1, "x": 0, "v": "fast"}', "'v' must be a number"),
    ],
)
def test_a_bad_avatar_state_is_refused(field, problem):
    text = f'{{"type": "position", "seq": 1, "x": 0, "avatar": {field}}}'
    with pytest.raises(ProtocolError, match=problem):
        parse_participant_message(text)
