"""The emulated internet's spec, delays and delivery times (`mirror_avatar.remote.network`)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from mirror_avatar.common.errors import InputError
from mirror_avatar.remote.network import Delay, Stall, due_time, lane_rng, parse_network


@pytest.mark.parametrize(
    ("text", "up", "down", "stalls"),
    [
        ("80+-25", (80, 25), (80, 25), ()),
        (" 40±15 ", (40, 15), (40, 15), ()),
        ("up=120+-40,down=40+-15", (120, 40), (40, 15), ()),
        ("120+-40,stall=5:1", (120, 40), (120, 40), ((5, 1),)),
        ("80,stall=5:1,stall=5.5:1,stall=9:0.25", (80, 0), (80, 0), ((5, 1.5), (9, 0.25))),
        ("none", (0, 0), (0, 0), ()),
    ],
)
def test_a_spec_reads_as_declared_and_prints_back(text, up, down, stalls):
    network = parse_network(text)
    assert network.up == Delay(*up) and network.down == Delay(*down)
    assert network.stalls == tuple(Stall(*stall) for stall in stalls)
    assert parse_network(str(network)) == network


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("", "'' is not a delay"),
        ("fast", "'fast' is not a delay"),
        ("80+-", "'80+-' is not a delay"),
        ("-5", "'-5' is not a delay"),
        ("up=80", "no down delay"),
        ("80,80", "up delay given twice"),
        ("80,jitter=5", "'jitter=5' is not a delay or stall"),
        ("80,stall=5", "stall='5' is not START:SECONDS"),
        ("80,stall=5:0", "the duration above 0"),
        ("80,stall=700:1", "from 0 to 600 s"),
        ("20000", "delays are up to 10000 ms"),
    ],
)
def test_a_bad_spec_is_refused_in_one_line_naming_the_option(text, says):
    with pytest.raises(InputError) as refused:
        parse_network(text)
    line = str(refused.value)
    assert line.startswith("--network: ") and says in line and "\n" not in line
    assert "80+-25" in line or "stall=5:1" in line  # an example of what to give


def test_a_chunk_is_due_after_its_delay_in_order_and_held_by_a_stall():
    stalls = (Stall(1.0, 0.5),)
    assert due_time(0.2, 80.0, -math.inf, stalls) == (pytest.approx(0.28), "delay")
    assert due_time(0.21, 30.0, 0.28, stalls) == (0.28, "order")  # not before the one before
    assert due_time(0.95, 80.0, 0.9, stalls) == (1.5, "stall")  # due in the stall: at its end
    assert due_time(1.2, 10.0, 1.5, stalls) == (1.5, "stall")  # behind a held chunk
    assert due_time(1.2, 400.0, 1.5, stalls) == (pytest.approx(1.6), "delay")  # due after it


def test_delays_are_normal_truncated_at_zero_and_reproduced_by_the_seed():
    delay = Delay(10.0, 20.0)  # half the untruncated normal lies below 0
    rng = lane_rng(5, 1, "up")
    draws = np.array([delay.draw(rng) for _ in range(4000)])
    assert draws.min() >= 0.0
    truncated = stats.truncnorm(-10.0 / 20.0, np.inf, loc=10.0, scale=20.0)
    assert stats.kstest(draws, truncated.cdf).pvalue > 0.001
    again = lane_rng(5, 1, "up")
    assert [delay.draw(again) for _ in range(10)] == list(draws[:10])
    other = lane_rng(5, 1, "down")
    assert [delay.draw(other) for _ in range(10)] != list(draws[:10])
    assert Delay(80.0).draw(rng) == 80.0
