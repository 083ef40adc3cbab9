"""How a page sees its partners when links differ: as they arrive, equalised, or predicted.

A partner's position of sample k, recorded at server time ``t_k`` (s, the clock that stamps the
samples), reaches a page one downlink later. Three handlings (METHODS section 19):

- ``as_arrives``: drawn on the first animation frame after it arrives;
- ``equalised`` (local lag, Mauve et al. 2004): held by the page until ``t_k + L`` (its clock
  mapped onto the server's, `due_page_ms`), ``L`` a declared lag or the slowest page's one-way
  delay (`one_way_ms` at `LAG_QUANTILE`), so that every page draws sample k at the same time;
- ``predicted`` (first-order dead reckoning): drawn as it arrives, at the position the
  recording is expected to show ``h`` after ``t_k``: the partner's newest sample extrapolated
  (`dead_reckon`) to the read time the recording shows then (`recorded_read_s`), along the line
  fitted on its samples read within `FIT_WINDOW_S`, each at the time it was read (a page's
  pointer sample: its read time on the server's clock; an avatar's: its sample's time), not at
  the control ticks that recorded it.

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

FIT_WINDOW_S = 0.09
"""Time (s) before a partner's newest sample within which its samples are read that its velocity
is fitted on (**choice**: three 30 ms control periods, four samples of a page that reads its
pointer once a period, five or six at 60 Hz: long enough to average a pointer's quantisation,
short enough to follow a reversal)."""

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


def dead_reckon(read_s: Array, x: Array, to_s: float, bounds: tuple[float, float]) -> float:
    """Return a partner's position extrapolated from its newest sample to the read time ``to_s``.

    ``x_n + v (to_s - t_n)``, with ``(t_n, x_n)`` the newest sample and ``v`` the slope of the
    least-squares line through the samples read within `FIT_WINDOW_S` of it (none moving with
    one), clipped to ``bounds``. Each sample is fitted at its own read time: samples read at
    uneven times, and a tick that recorded no new sample, do not bend the slope.

    Parameters
    ----------
    read_s
        When each sample was read (s, increasing), shape (n,).
    x
        Its position (units), shape (n,).
    to_s
        The read time to extrapolate to (s).
    bounds
        The playing range (units).
    """
    recent = read_s >= read_s[-1] - FIT_WINDOW_S
    t, y = read_s[recent], x[recent]
    centred = t - t.mean()
    spread = float(centred @ centred)
    slope = float(centred @ (y - y.mean())) / spread if spread > 0.0 else 0.0
    return float(np.clip(x[-1] + slope * (to_s - read_s[-1]), *bounds))


def recorded_read_s(display_s: float, read_s: Array, arrived_s: Array) -> float:
    """Return the read time (s) of the partner's position the recording shows at ``display_s``.

    The recording holds a partner's newest sample from its arrival at the server, so at
    ``display_s`` (s, the server's clock) it shows the position read one uplink earlier: the
    median of ``arrived_s - read_s`` (s) over the samples read within `FIT_WINDOW_S` of the
    newest (none for a partner sampled on the server's own ticks).
    """
    recent = read_s >= read_s[-1] - FIT_WINDOW_S
    return display_s - float(np.median(arrived_s[recent] - read_s[recent]))


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
