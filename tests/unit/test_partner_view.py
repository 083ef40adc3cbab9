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
    recorded_read_s,
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


def test_dead_reckoning_fits_the_slope_of_the_samples_read_within_its_window():
    # x = (t / 0.03)^2 / 100 read at t = 0, 0.03, 0.06, 0.09 s: in steps of 0.03 s the
    # least-squares slope is 15 / 5 = 3 (see the comment below), 1 unit/s after scaling;
    # 0.015 s past the newest: 0.09 + 0.015 = 0.105
    read = np.array([0.0, 0.03, 0.06, 0.09])
    x = np.array([0.0, 1.0, 4.0, 9.0]) / 100.0
    # sum (t - 1.5)(x - 3.5) = 5.25 + 1.25 + 0.25 + 8.25 = 15; sum (t - 1.5)^2 = 5
    assert dead_reckon(read, x, 0.105, BOUNDS) == pytest.approx(0.105)


def test_dead_reckoning_uses_only_the_samples_read_within_its_window():
    # an old jump 0.1 s before the newest, then a ramp of 0.01 per 0.03 s: 1/3 unit/s; 0.15 s
    # past the newest: -0.07 + 0.05
    read = np.array([0.0, 0.11, 0.14, 0.17, 0.20])
    x = np.array([0.4, -0.1, -0.09, -0.08, -0.07])
    assert dead_reckon(read, x, 0.35, BOUNDS) == pytest.approx(-0.02)


def test_dead_reckoning_stays_in_range_and_holds_a_single_sample():
    ramp = np.array([0.40, 0.44, 0.48])
    assert dead_reckon(np.array([0.0, 0.03, 0.06]), ramp, 1.06, BOUNDS) == pytest.approx(0.5)
    assert dead_reckon(np.array([0.0]), np.array([0.2]), 1.0, BOUNDS) == pytest.approx(0.2)


def test_the_recording_shows_a_position_one_median_uplink_old():
    # uplinks 0.5 (read 0.1 s before the newest: outside the window), 0.10, 0.20, 0.15, 0.12
    read = np.array([0.0, 0.1, 0.13, 0.16, 0.19])
    arrived = read + np.array([0.5, 0.10, 0.20, 0.15, 0.12])
    assert recorded_read_s(10.0, read, arrived) == pytest.approx(10.0 - 0.135)
    ticks = np.array([1.0, 1.03])
    assert recorded_read_s(1.2, ticks, ticks) == 1.2


def test_linear_motion_read_at_jittered_times_is_predicted_exactly_unlike_from_held_ticks():
    """A page reads x = 0.1 + 0.8 t every 30 ms +- 10 ms, sends each read over a link of
    120 +- 40 ms that keeps the order, and the server records at each 30 ms tick the newest
    arrived (held when none arrived). Fitted at the reads' times, the prediction is the motion
    itself; fitted on the ticks, as the recording holds the reads, it is not."""

    def motion(t):
        return 0.1 + 0.8 * t

    rng = np.random.default_rng(49)
    read = np.arange(0.0, 3.0, 0.03) + rng.uniform(-0.01, 0.01, 100)
    arrived = np.maximum.accumulate(read + np.clip(rng.normal(0.12, 0.04, 100), 0.0, None))
    ticks = np.arange(0.3, 3.0, 0.03)
    newest = np.searchsorted(arrived, ticks, side="right") - 1
    held = np.mean(newest[1:] == newest[:-1])
    assert held > 0.1  # the recording holds a read at some ticks
    horizon = 0.15
    exact, from_ticks = [], []
    for k in range(10, len(ticks)):
        known = slice(0, newest[k] + 1)
        to_s = recorded_read_s(ticks[k] + horizon, read[known], arrived[known])
        exact.append(
            dead_reckon(read[known], motion(read[known]), to_s, (-5.0, 5.0)) - motion(to_s)
        )
        recorded = motion(read[newest[k - 3 : k + 1]])
        from_ticks.append(
            dead_reckon(ticks[k - 3 : k + 1], recorded, ticks[k] + horizon, (-5.0, 5.0))
            - motion(to_s)
        )
    assert np.abs(exact).max() < 1e-12
    assert np.sqrt(np.mean(np.square(from_ticks))) > 0.02


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
