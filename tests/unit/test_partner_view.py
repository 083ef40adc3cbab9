"""Equalising and predicting a partner's view: the arithmetic against hand-computed values, and
what the view file records of a page's draws."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from mirror_avatar.lab.running.messages import Shown, parse_participant_message
from mirror_avatar.lab.running.partner_frames import JitteredLink
from mirror_avatar.lab.running.views import SentFrame, ViewLog
from mirror_avatar.realtime.messages import ProtocolError
from mirror_avatar.realtime.partner_view import (
    dead_reckon,
    displayed_delays_ms,
    displayed_errors,
    due_page_ms,
    jitter_draw,
    jittered_delay_s,
    one_way_ms,
    view_summary,
)

BOUNDS = (-0.5, 0.5)


def test_one_way_is_half_a_quantile_of_the_round_trips():
    assert one_way_ms([40.0, 300.0, 42.0, 41.0, 44.0]) == 21.0  # median 42
    # p95 of 1..21 (linear): 1 + 0.95 * 20 = 20; halved
    assert one_way_ms([float(v) for v in range(1, 22)], 0.95) == 10.0
    assert one_way_ms([]) is None


def test_a_sample_is_due_its_lag_after_its_time_on_the_page_clock():
    # sample at server 12.5 s, lag 150 ms, page clock 2000 ms behind: 12650 - 2000 ms
    assert due_page_ms(12.5, 150.0, 2000.0) == 10_650.0
    assert due_page_ms(12.5, 150.0, -500.0) == 13_150.0


def test_dead_reckoning_fits_the_slope_of_the_last_four_samples():
    # x = t^2 at t = 0, 1, 2, 3 (period 1): least-squares slope 15 / 5 = 3 (see the comment
    # below); 9 + 3 * 0.5 = 10.5, scaled by 1/100 to lie in the playing range
    history = np.array([[0.0], [1.0], [4.0], [9.0]]) / 100.0
    # sum (t - 1.5)(x - 3.5) = 5.25 + 1.25 + 0.25 + 8.25 = 15; sum (t - 1.5)^2 = 5
    assert dead_reckon(history, 1.0, 0.5, BOUNDS) == pytest.approx([0.105])


def test_dead_reckoning_uses_only_the_last_samples_and_the_period():
    # an old jump, then a ramp of 0.01 a sample at 0.03 s: v = 1/3 unit/s; 0.15 s ahead: +0.05
    history = np.array([[0.4, 0.0], [-0.2, 0.0], [-0.1, 0.0], [-0.09, 0.0], [-0.08, 0.0],
                        [-0.07, 0.0]])  # fmt: skip
    assert dead_reckon(history, 0.03, 0.15, BOUNDS) == pytest.approx([-0.02, 0.0])


def test_dead_reckoning_stays_in_range_and_holds_a_single_sample():
    ramp = np.array([[0.40], [0.44], [0.48]])
    assert dead_reckon(ramp, 0.03, 1.0, BOUNDS) == pytest.approx([0.5])
    assert dead_reckon(np.array([[0.2]]), 0.03, 1.0, BOUNDS) == pytest.approx([0.2])


def test_delays_and_errors_against_the_recording():
    shown_s = np.array([1.17, 1.20])
    sample_s = np.array([1.02, 1.05])
    assert displayed_delays_ms(shown_s, sample_s) == pytest.approx([150.0, 150.0])
    times = np.array([1.14, 1.17, 1.20, 1.23])
    truth = np.array([0.0, 0.03, 0.06, 0.09])
    # drawn 0.01 and 0.075 at 1.17 and 1.20 s: the recording had 0.03 and 0.06 there
    errors = displayed_errors(shown_s, np.array([0.01, 0.075]), times, truth)
    assert errors == pytest.approx([-0.02, 0.015])
    # between samples: at 1.185 s the recording is 0.045
    between = displayed_errors(np.array([1.185]), np.array([0.045]), times, truth)
    assert between == pytest.approx([0.0])


def test_the_summary_gives_mean_p95_and_rms():
    summary = view_summary(np.arange(1.0, 21.0), np.array([0.03, -0.04]))
    assert summary["frames"] == 20
    assert summary["delay_ms"]["mean"] == 10.5
    assert summary["delay_ms"]["p95"] == pytest.approx(19.05)  # 1 + 0.95 * 19
    assert summary["error_rms"] == pytest.approx(np.sqrt((0.0009 + 0.0016) / 2))
    assert view_summary(np.array([]), None)["error_rms"] is None


def test_the_view_log_writes_and_judges_what_a_page_drew(tmp_path):
    log = ViewLog(tmp_path / "trial-01_view.csv", ["P1", "P2"])
    log.sent("P1", 5, SentFrame((1,), 1.02, (0.01,)))
    log.sent("P1", 6, SentFrame((1,), 1.05, (None,)))  # hidden: not drawn
    log.shown("P1", [(5, 900.0, 1.17), (6, 930.0, 1.20), (7, 960.0, 1.23)])  # 7: never sent
    log.shown("P1", [(5, 990.0, 1.26)])  # reported twice: kept once
    log(np.zeros(3))
    log.close()
    rows = (tmp_path / "trial-01_view.csv").read_text().splitlines()
    assert rows == ["label,partner,k,sample_s,page_ms,shown_s,x",
                    "P1,P2,5,1.020000,900.000,1.170000,0.01"]  # fmt: skip
    times = np.array([1.14, 1.17, 1.20])
    positions = np.array([[0.0, 0.0, 0.0], [0.0, 0.03, 0.06]])
    summary = log.summary("P1", times, positions)
    assert summary["frames"] == 1 and summary["delay_ms"]["mean"] == pytest.approx(150.0)
    assert summary["error_rms"] == pytest.approx(0.02)  # drew 0.01 where P2 was at 0.03
    assert log.summary("P2", times, positions) is None


@pytest.mark.parametrize(
    ("message", "problem"),
    [
        ({"k": [1, 2], "t": [3.0]}, "shown: 'k' and 't' must be lists of the same length"),
        ({"k": [], "t": []}, "shown: 1 to 20 frames per message"),
        ({"k": [-1], "t": [3.0]}, "shown: 'k' must be a non-negative integer"),
        ({"k": [1], "t": ["soon"]}, "shown: 't' must be a number"),
    ],
)
def test_a_bad_shown_message_is_refused(message, problem):
    with pytest.raises(ProtocolError, match=re.escape(problem)):
        parse_participant_message(json.dumps({"type": "shown"} | message))
    parsed = parse_participant_message('{"type": "shown", "k": [4, 5], "t": [10.5, 27.1]}')
    assert parsed == Shown([4, 5], [10.5, 27.1])


@pytest.mark.parametrize("distribution", ["normal", "uniform", "exponential"])
def test_a_jitter_has_a_zero_mean_and_its_declared_sd(distribution):
    rng = np.random.default_rng(49)
    draws = np.array([jitter_draw(rng, distribution, 0.05) for _ in range(40_000)])
    # the mean within 4 standard errors of 0; the SD within 2 % of the declared
    assert abs(draws.mean()) < 4 * 0.05 / np.sqrt(draws.size)
    assert draws.std() == pytest.approx(0.05, rel=0.02)
    skew = np.mean((draws - draws.mean()) ** 3) / draws.std() ** 3
    assert skew == pytest.approx({"normal": 0.0, "uniform": 0.0, "exponential": 2.0}[distribution],
                                 abs=0.15)  # fmt: skip


def test_a_jittered_delay_stays_within_none_and_four_sds():
    assert jittered_delay_s(0.3, 0.05, 0.02) == pytest.approx(0.35)
    assert jittered_delay_s(0.03, -0.2, 0.02) == 0.0
    assert jittered_delay_s(0.3, 0.5, 0.02) == pytest.approx(0.38)  # 0.3 + 4 * 0.02


def test_a_jittered_link_delivers_in_order_the_newest_sample_due():
    # at T = 0.03 s: sample 0 delayed 0.09 s holds 1 and 2 (due at once, at 0.09 s, behind it);
    # sample 3 delayed 0.12 s (due 0.21 s) holds 4 to 6, shown together with 7 at 0.21 s
    link = JitteredLink(np.random.default_rng(0))
    delays = [0.09, 0.0, 0.0, 0.12, 0.0, 0.0, 0.0, 0.0, 0.03]
    shown = [link.deliver(k, delay) for k, delay in enumerate(delays)]
    assert shown == [None, None, None, 2, 2, 2, 2, 7, 7]
