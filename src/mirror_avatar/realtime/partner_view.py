"""How a page sees its partners when links differ: as they arrive, equalised, or predicted.

A partner's position of sample k, recorded at server time ``t_k`` (s, the clock that stamps the
samples), reaches a page one downlink later. Three handlings (METHODS section 19):

- ``as_arrives``: drawn on the first animation frame after it arrives;
- ``equalised`` (local lag, Mauve et al. 2004): held by the page until ``t_k + L`` (its clock
  mapped onto the server's, `due_page_ms`), ``L`` a declared lag or the slowest page's one-way
  delay (`one_way_ms` at `LAG_QUANTILE`), so that every page draws sample k at the same time;
- ``predicted`` (first-order dead reckoning): drawn as it arrives, at the position extrapolated
  ``h`` ahead from the partner's last `FIT_SAMPLES` samples (`dead_reckon`).

A condition's fixed delay of the partners may vary from sample to sample: a zero-mean jitter of
a declared distribution and SD is added to each sample's (`jitter_draw`), never below none nor
beyond `JITTER_SPAN` SDs (`jittered_delay_s`).

What a page drew is judged against the recording (`displayed_delays_ms`, `displayed_errors`):
the delay is the draw's time on the server's clock minus ``t_k``, the error the drawn position
minus the partner's recorded position at the draw's time (linear between samples).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.realtime.latency import summarise

HANDLINGS = ("as_arrives", "equalised", "predicted")
"""How a page draws its partners (see the module docstring)."""

FIT_SAMPLES = 4
"""Samples a partner's velocity is fitted on (**choice**: at the 30 ms control period, the last
90 ms: long enough to average a pointer's quantisation, short enough to follow a reversal)."""

JITTERS = ("normal", "uniform", "exponential")
"""Distributions of a delay's jitter: normal; uniform; exponential, shifted to a zero mean
(skewed to long delays, as a queue's)."""

JITTER_SPAN = 4.0
"""SDs of jitter a delay may exceed its declared one by (**choice**: a normal draw goes beyond
it once in 30 000, an exponential one once in 150)."""

LAG_QUANTILE = 0.95
"""Quantile of the slowest page's round trips whose half is a measured lag (**choice**: a frame
that arrives after its due time is drawn late, so the lag covers nearly every frame's delay, as
local lag must to avoid showing the pages different moments; Mauve et al. 2004)."""

Array = NDArray[np.float64]


def one_way_ms(round_trips_ms: Sequence[float], quantile: float = 0.5) -> float | None:
    """Return a link's one-way delay (ms): half a quantile of its round trips (None if none).

    Half the round trip takes the two directions as equal, as the page clock's offset does
    (`mirror_avatar.realtime.page_clock`); the default quantile is the median.
    """
    if not len(round_trips_ms):
        return None
    return float(np.quantile(np.asarray(round_trips_ms, dtype=np.float64), quantile)) / 2.0


def jitter_draw(rng: np.random.Generator, distribution: str, sd_s: float) -> float:
    """Return one draw (s) of a zero-mean jitter of SD ``sd_s`` (s) from ``distribution``.

    ``normal``: N(0, sd); ``uniform``: U(-sqrt(3) sd, sqrt(3) sd); ``exponential``:
    Exp(mean sd) - sd.
    """
    if distribution == "normal":
        return float(rng.normal(0.0, sd_s))
    if distribution == "uniform":
        half = math.sqrt(3.0) * sd_s
        return float(rng.uniform(-half, half))
    return float(rng.exponential(sd_s)) - sd_s


def jittered_delay_s(delay_s: float, jitter_s: float, sd_s: float) -> float:
    """Return a sample's delay (s): ``delay_s`` plus its jitter, within 0 and `JITTER_SPAN` SDs.

    ``jitter_s`` is the sample's draw (s, `jitter_draw`), ``sd_s`` the jitter's SD (s).
    """
    return min(max(delay_s + jitter_s, 0.0), delay_s + JITTER_SPAN * sd_s)


def due_page_ms(sample_s: float, lag_ms: float, offset_ms: float) -> float:
    """Return the page time (ms) at which a page draws a sample recorded at ``sample_s``.

    Parameters
    ----------
    sample_s
        The sample's time (s, the server's clock).
    lag_ms
        The declared or measured lag ``L`` (ms).
    offset_ms
        The page's clock offset, server time minus page time (ms).
    """
    return sample_s * 1000.0 + lag_ms - offset_ms


def dead_reckon(
    history: Array, period: float, horizon_s: float, bounds: tuple[float, float]
) -> Array:
    """Return each player's position extrapolated ``horizon_s`` beyond its last sample.

    ``x_k + v h``, with ``v`` the slope of the least-squares line through the last
    `FIT_SAMPLES` samples (fewer at a trial's start; none moving with one), clipped to
    ``bounds``.

    Parameters
    ----------
    history
        Positions (units), shape (n_samples, n_players), oldest first, ``period`` (s) apart.
    period
        Time between samples (s).
    horizon_s
        How far ahead (s).
    bounds
        The playing range (units).
    """
    recent = history[-FIT_SAMPLES:]
    last = recent[-1]
    if len(recent) < 2:
        return np.clip(last, *bounds)
    t = np.arange(len(recent), dtype=np.float64) * period
    centred = t - t.mean()
    slope = centred @ (recent - recent.mean(axis=0)) / (centred @ centred)
    return np.clip(last + slope * horizon_s, *bounds)


def displayed_delays_ms(shown_s: Array, sample_s: Array) -> Array:
    """Return each draw's delay (ms): its time minus its sample's (both s, the server's clock)."""
    return (shown_s - sample_s) * 1000.0


def displayed_errors(shown_s: Array, shown_x: Array, times_s: Array, truth_x: Array) -> Array:
    """Return each drawn position minus the partner's recorded position at the draw's time.

    Parameters
    ----------
    shown_s, shown_x
        Each draw's time (s, the server's clock) and the position drawn (units).
    times_s, truth_x
        The partner's recorded samples: their times (s, increasing) and positions (units);
        linear between them, the first or last outside them.
    """
    return shown_x - np.interp(shown_s, times_s, truth_x)


def view_summary(delays_ms: Array, errors: Array | None) -> dict[str, object]:
    """Summarise a page's view of a partner: the draws, their delays (ms) and the RMS error.

    Returns
    -------
    dict
        ``frames`` (draws), ``delay_ms`` (`mirror_avatar.realtime.latency.summarise`) and
        ``error_rms`` (units; None without ``errors`` or draws).
    """
    rms = None if errors is None or not errors.size else float(np.sqrt(np.mean(errors**2)))
    return {"frames": int(delays_ms.size), "delay_ms": summarise(delays_ms.tolist()),
            "error_rms": rms}  # fmt: skip
