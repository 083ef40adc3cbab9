"""The field's measures of a session, each beside its chance level (METHODS section 12).

`session_measures` is the companion of `mirror_avatar.metrics.summary.session_metrics`: it takes
any `Session` (simulated, live, lab, imported, BIDS) and returns co-confidence, jitter,
synchrony episodes, leadership and transfer entropy, and for every coordination measure a
surrogate distribution and a p-value (`mirror_avatar.metrics.surrogates`). Keys:

- two players: ``co_confidence_rate`` (share of time), ``co_confidence_count``,
  ``co_confidence_mean_length`` (s), ``co_confidence_segments`` (start and end in session time
  (s), ``dv``, ``dt`` (s)); ``jitter_index_player_<k>``; ``synchrony_share``,
  ``synchrony_entries``, ``synchrony_exits``, ``synchrony_mean_dwell`` and
  ``synchrony_mean_gap`` (s); ``leader`` (0, 1 or ``"none"``), ``leader_share``,
  ``leader_lag_s`` (s), ``leadership_strength`` (mean picked-peak correlation, windows without
  a peak counting 0); ``transfer_entropy_0_to_1`` and ``_1_to_0`` (bits); and
  ``max_cross_correlation``;
- three or more: ``jitter_index_player_<k>``, ``transfer_entropy_<i>_to_<j>`` for every ordered
  pair and each player's ``influence_player_<i>`` (mean transfer entropy to the others, bits);
- ``<measure>_p_value`` beside each tested measure (`mirror_avatar.metrics.registry`, which
  declares every key's words, unit and test); ``time_lag_p_value`` is the
  p-value of the cross-correlation peak that fixes the time lag; ``surrogates`` records the
  kind, number, smallest shift and seed.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.constraints import Constraint, Interval, Options, check
from mirror_avatar.common.errors import InputError
from mirror_avatar.metrics import co_confidence, jitter, leadership, registry, synchrony_episodes
from mirror_avatar.metrics import transfer_entropy as te
from mirror_avatar.metrics.coordination import compute_phase, cross_correlation_peaks, wrap_phase
from mirror_avatar.metrics.quantities import Quantities
from mirror_avatar.metrics.surrogates import (
    MIN_SHIFT,
    WeakNull,
    kuramoto_weak_null,
    p_value,
    pseudo_session,
    shift_offsets,
    shifted,
)
from mirror_avatar.sessions.session import Session

Array = NDArray[np.float64]

N_SURROGATES = 99
"""Surrogates per session by default (p-values down to 0.01)."""

MAX_SURROGATES = 9999
"""Most surrogates per session (p-values down to 1e-4); each is drawn, measured and dropped in
turn (a pair's circular shifts a few at a time, `SHIFT_SAMPLES`), so memory does not grow with
their number, but time does."""

SHIFT_SAMPLES = 2**15
"""Most samples of a pair's shifted player 1 measured together (`_shift_statistics`): 49
surrogates of a 20 s trial at 33 Hz at once, one of a 20 minute trial, so that memory stays
within a few MB whatever the number of surrogates."""

MAX_SECONDS = 600.0
"""Longest window, step, lag, segment or shift (s) of the measures: ten minutes, beyond any
use in the field, and a bound on the memory of a window's running sums."""

MAX_TE_STATES = 2**24
"""Most joint states ``te_bins ** (te_history + 2)`` of transfer entropy: pyinform allocates
a table of them (a few hundred MB at this bound) and fails, or crashes, beyond."""

_SECONDS = Interval(float, 0.0, MAX_SECONDS, "right", "s")
_SHARE = Interval(float, 0.0, 1.0)
CONSTRAINTS: dict[str, Constraint] = {
    "min_duration": _SECONDS,
    "jitter_threshold": Interval(float, 0.0, None, "neither"),
    "dv_threshold": Interval(float, 0.0, 2.0, "right"),
    "dv_window": _SECONDS,
    "rest_fraction": _SHARE,
    "sync_window": _SECONDS,
    "sync_threshold": _SHARE,
    "lead_window": _SECONDS,
    "lead_step": _SECONDS,
    "lead_max_lag": _SECONDS,
    "lead_min_peak": Interval(float, -1.0, 1.0),
    "leader_share": _SHARE,
    "lead_signal": Options(("velocity", "position")),
    "te_bins": Interval(int, 2, 64),
    "te_history": Interval(int, 1, 16),
    "te_step": _SECONDS,
    "n_surrogates": Interval(int, 0, MAX_SURROGATES),
    "surrogates": Options(("shift", "pseudo")),
    "min_shift": Interval(float, 0.0, MAX_SECONDS, unit="s"),
    "seed": Interval(int, 0, 2**32 - 1),
}
"""The allowed values of each open parameter of `MeasureOptions` (the jitter band excepted: it
is fixed by the literature). dV is at most 2, shares and the windowed CV lie in [0, 1] and
correlations in [-1, 1]."""


@dataclass(frozen=True)
class MeasureOptions:
    """The open parameters of the measures, each a **choice** (METHODS section 12).

    Attributes
    ----------
    min_duration, jitter_threshold, dv_threshold, dv_window, rest_fraction
        Co-confidence (`mirror_avatar.metrics.co_confidence.find_co_confidence`).
    jitter_band
        Jitter band (Hz).
    sync_window, sync_threshold
        Synchrony episodes (s, windowed phase locking).
    lead_window, lead_step, lead_max_lag, lead_min_peak, leader_share
        Leadership (`mirror_avatar.metrics.leadership`); ``lead_signal`` ``"velocity"`` or
        ``"position"``.
    te_bins, te_history, te_step
        Transfer entropy (`mirror_avatar.metrics.transfer_entropy`).
    n_surrogates, surrogates, min_shift, seed
        Surrogates per session (0: none), their kind (``"shift"`` or ``"pseudo"``), the
        smallest circular shift (s) and the seed of their draws.
    """

    min_duration: float = co_confidence.MIN_DURATION
    jitter_threshold: float = co_confidence.JITTER_THRESHOLD
    dv_threshold: float = co_confidence.DV_THRESHOLD
    dv_window: float = co_confidence.DV_WINDOW
    rest_fraction: float = co_confidence.REST_FRACTION
    jitter_band: tuple[float, float] = jitter.JITTER_BAND
    sync_window: float = synchrony_episodes.WINDOW
    sync_threshold: float = synchrony_episodes.THRESHOLD
    lead_window: float = leadership.WINDOW
    lead_step: float = leadership.STEP
    lead_max_lag: float = leadership.MAX_LAG
    lead_min_peak: float = leadership.MIN_PEAK
    leader_share: float = leadership.LEADER_SHARE
    lead_signal: Literal["velocity", "position"] = "velocity"
    te_bins: int = te.BINS
    te_history: int = te.HISTORY
    te_step: float = te.STEP
    n_surrogates: int = N_SURROGATES
    surrogates: Literal["shift", "pseudo"] = "shift"
    min_shift: float = MIN_SHIFT
    seed: int = 0

    def __post_init__(self) -> None:
        """Check every parameter against its declaration (`CONSTRAINTS`).

        Raises
        ------
        mirror_avatar.common.constraints.ConstraintError
            A parameter outside its range, or transfer entropy with more than `MAX_TE_STATES`
            joint states.
        """
        for name, constraint in CONSTRAINTS.items():
            check(name, getattr(self, name), constraint)
        if self.te_bins ** (self.te_history + 2) > MAX_TE_STATES:
            raise InputError(
                "te_bins, te_history",
                f"{self.te_bins} bins with a history of {self.te_history} make "
                f"{self.te_bins ** (self.te_history + 2)} joint states, more than "
                f"{MAX_TE_STATES}; lower --te-bins or --te-history",
            )


@dataclass
class Measures:
    """A session's measures.

    ``values`` (JSON-ready, keys in the module docstring), the time-resolved ``details`` figures
    draw (``co_confidence``, ``leadership``, ``jitter``, ``synchrony``, ``start``: the session
    time of sample 0), ``null``, each tested measure's surrogate values, and ``notes``, one
    line for each measure the session is too short for.
    """

    values: dict[str, Any] = field(default_factory=dict)
    details: dict[str, Any] = field(default_factory=dict)
    null: dict[str, Array] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def _cc(v: Array, rate: float, o: MeasureOptions) -> co_confidence.CoConfidence:
    return co_confidence.find_co_confidence(
        v[0], v[1], rate, o.min_duration, o.jitter_threshold, o.dv_threshold, o.dv_window,
        o.rest_fraction, o.jitter_band,
    )  # fmt: skip


def _leadership(x: Array, v: Array, rate: float, o: MeasureOptions) -> leadership.Leadership | None:
    """Leadership of the pair; None when the session is shorter than a window and its lags."""
    if x.shape[1] < round(o.lead_window * rate) + 2 * round(o.lead_max_lag * rate):
        return None
    s = v if o.lead_signal == "velocity" else x
    return leadership.compute_leadership(
        s[0], s[1], rate, o.lead_window, o.lead_step, o.lead_max_lag, o.lead_min_peak
    )


def _te(v: Array, i: int, j: int, rate: float, o: MeasureOptions) -> float:
    return te.transfer_entropy(v[i], v[j], rate, o.te_history, o.te_bins, o.te_step)


@dataclass(frozen=True)
class _Pair:
    """The quantities of a pair that depend on the options, each computed once."""

    co_confidence: co_confidence.CoConfidence
    leadership: leadership.Leadership | None


def _pair(q: Quantities, o: MeasureOptions) -> _Pair:
    return _Pair(_cc(q.velocities, q.rate, o), _leadership(q.positions, q.velocities, q.rate, o))


def coordination_statistics(x: Array, v: Array, rate: float, o: MeasureOptions) -> dict[str, float]:
    """Compute the tested measures of N moving players (`registry.measures_tested` names them).

    Parameters
    ----------
    x, v
        Positions (units) and velocities (units/s), shape (N, n), uniform at ``rate`` (Hz).
    rate
        Sampling rate (Hz).
    o
        Options.
    """
    return _statistics(Quantities(x, v, rate), o)


def _statistics(q: Quantities, o: MeasureOptions, pair: _Pair | None = None) -> dict[str, float]:
    """Compute the tested measures from a session's quantities (a pair's: ``pair``, if known)."""
    v, rate = q.velocities, q.rate
    if v.shape[0] > 2:
        out = {"group_synchronisation": float(q.cluster.group.mean())}
        for i in range(v.shape[0]):
            for j in range(v.shape[0]):
                if i != j:
                    out[f"transfer_entropy_{i}_to_{j}"] = _te(v, i, j, rate, o)
        return out
    pair = pair or _pair(q, o)
    strength, share = _leading(pair.leadership, rate, o)
    return {
        "phase_locking": q.phase_locking,
        "rmse": q.rmse,
        "max_cross_correlation": q.cross_correlation_peak[1],
        "co_confidence_rate": pair.co_confidence.rate,
        "leadership_strength": strength,
        "leader_share": share,
        "transfer_entropy_0_to_1": _te(v, 0, 1, rate, o),
        "transfer_entropy_1_to_0": _te(v, 1, 0, rate, o),
    }


def _leading(
    lead: leadership.Leadership | None, rate: float, o: MeasureOptions
) -> tuple[float, float]:
    """Return the tested leadership measures: the strength and the leader's share (NaN: none)."""
    if lead is None:
        return float("nan"), float("nan")
    return float(np.nan_to_num(lead.peak_values).mean()), lead.leader(rate, o.leader_share)[1]


def _shift_statistics(
    q: Quantities, shifts: NDArray[np.int64], o: MeasureOptions
) -> dict[str, Array]:
    """Compute the tested measures of a pair's circular-shift surrogates, all at once.

    Equal to `coordination_statistics` of each surrogate (player 1 rolled by each of ``shifts``,
    samples, shape (S,)) up to rounding: player 0's phase, standardised windows and states are
    the session's, and player 1's shifted series are filtered and correlated together.

    Returns
    -------
    dict
        Each measure of `mirror_avatar.metrics.registry.measures_tested` (two players): its value
        for each surrogate, shape (S,).
    """
    x, v, rate = q.positions, q.velocities, q.rate
    index = (np.arange(x.shape[1])[None, :] - shifts[:, None]) % x.shape[1]
    x1, v1 = x[1][index], v[1][index]
    relative = wrap_phase(q.phases[0] - compute_phase(x1))
    masks = co_confidence.co_confidence_masks(
        v[0], v1, rate, o.min_duration, o.jitter_threshold, o.dv_threshold, o.dv_window,
        o.rest_fraction, o.jitter_band, jitter.FILTER_ORDER,
    )[0]  # fmt: skip
    out = {
        "phase_locking": np.abs(np.mean(np.exp(1j * relative), axis=-1)),
        "rmse": np.sqrt(np.mean((x[0] - x1) ** 2, axis=-1)),
        "max_cross_correlation": cross_correlation_peaks(x[0], x1, rate)[1],
        "co_confidence_rate": masks.mean(axis=-1),
    }
    leading = [_leading(lead, rate, o) for lead in _shift_leadership(x, v, x1, v1, rate, o)]
    out["leadership_strength"], out["leader_share"] = np.array(leading).reshape(-1, 2).T
    stride = max(1, round(o.te_step * rate))
    states = [te.discretise(row, o.te_bins) for row in v]
    te_pairs = [(states[0], np.roll(states[1], k)) for k in shifts]
    out["transfer_entropy_0_to_1"] = np.array(
        [te.states_transfer_entropy(a, b, stride, o.te_history) for a, b in te_pairs]
    )
    out["transfer_entropy_1_to_0"] = np.array(
        [te.states_transfer_entropy(b, a, stride, o.te_history) for a, b in te_pairs]
    )
    return out


def _shift_leadership(
    x: Array, v: Array, x1: Array, v1: Array, rate: float, o: MeasureOptions
) -> list[leadership.Leadership | None]:
    """Leadership of player 0 with each shifted player 1 (``x1``, ``v1``: shape (S, n))."""
    if x.shape[1] < round(o.lead_window * rate) + 2 * round(o.lead_max_lag * rate):
        return [None] * x1.shape[0]
    s0, s1 = (v[0], v1) if o.lead_signal == "velocity" else (x[0], x1)
    times, lags, corr = leadership.windowed_cross_correlation(
        s0, s1, rate, o.lead_window, o.lead_step, o.lead_max_lag
    )
    peaks = (leadership.pick_peaks(lags, each, o.lead_min_peak) for each in corr)
    return [leadership.Leadership(times, lags, c, *p) for c, p in zip(corr, peaks, strict=True)]


def _surrogate_draws(
    q: Quantities, o: MeasureOptions, partners: Sequence[Session]
) -> Iterator[dict[str, Array]]:
    """Yield the tested measures of a session's surrogates, a few at a time, as ``o`` asks.

    Each item holds every tested measure of some surrogates, in the surrogates' order. A pair's
    circular shifts come `SHIFT_SAMPLES` samples of player 1 at a time (`_shift_statistics`);
    any other surrogate comes alone, its session drawn and measured in turn
    (`coordination_statistics`). Only the offsets (or the picks of partners) are drawn at once,
    so memory does not grow with the number of surrogates.
    """
    x, v, rate = q.positions, q.velocities, q.rate
    if o.surrogates == "pseudo":
        others = [p for p in partners if p.n_players == x.shape[0]]
        if not others:
            raise InputError(
                "--surrogates pseudo", "needs other sessions with as many players (or use shift)"
            )
        picks = np.random.default_rng(o.seed).permutation(len(others))[: o.n_surrogates]
        sessions = (
            (pseudo_session(x, others[k].positions), pseudo_session(v, others[k].velocities))
            for k in picks
        )
        yield from (_one(coordination_statistics(xs, vs, rate, o)) for xs, vs in sessions)
        return
    rng = np.random.default_rng(o.seed)
    offsets = shift_offsets(x.shape[1], x.shape[0], o.n_surrogates, round(o.min_shift * rate), rng)
    if x.shape[0] == 2:
        chunk = max(1, SHIFT_SAMPLES // x.shape[1])
        for first in range(0, len(offsets), chunk):
            yield _shift_statistics(q, offsets[first : first + chunk, 1], o)
        return
    for k in offsets:
        yield _one(coordination_statistics(shifted(x, k), shifted(v, k), rate, o))


def _one(draw: dict[str, float]) -> dict[str, Array]:
    """One surrogate's measures as `_surrogate_draws` yields them."""
    return {name: np.array([value]) for name, value in draw.items()}


def session_measures(
    session: Session, trim: float = 0.0, options: MeasureOptions | None = None,
    partners: Sequence[Session] = (), quantities: Quantities | None = None,
) -> Measures:  # fmt: skip
    """Compute the measures of a session and their chance levels (module docstring).

    Parameters
    ----------
    session
        Any session of two or more players (one player: only its jitter; a session shorter
        than `mirror_avatar.metrics.jitter.shortest_series` samples: none).
    trim
        Seconds left out at the start, as in `session_metrics`.
    options
        The open parameters; defaults `MeasureOptions()`.
    partners
        Other sessions (already trimmed) for pseudo-pair surrogates.
    quantities
        The session's shared quantities (after the trim), when its metrics use them too.
    """
    o = options or MeasureOptions()
    kept = session.trimmed(trim) if trim > 0 else session
    q = quantities or Quantities.of(kept)
    v, rate = q.velocities, q.rate
    out = Measures(details={"start": float(kept.times[0])})
    if kept.n_samples < jitter.shortest_series():
        return out
    players = [jitter.player_jitter(row, rate, o.jitter_band) for row in v]
    out.details["jitter"] = np.array([index for index, _ in players])
    for k, (_, value) in enumerate(players):
        out.values[f"jitter_index_player_{k}"] = value
    if kept.n_players < 2 or not q.moving:
        return out
    pair = _pair(q, o) if kept.n_players == 2 else None
    observed = _statistics(q, o, pair)
    out.values |= observed
    if pair is not None:
        out.values |= _dyad_values(q, pair, o, out.details)
        if "leadership" not in out.details:
            out.notes.append(
                f"no leadership: {kept.duration:g} s is shorter than --lead-window + 2 "
                f"--lead-max-lag ({o.lead_window + 2 * o.lead_max_lag:g} s)"
            )
    else:
        _add_influence(out.values, kept.n_players)
    if o.n_surrogates > 0:
        _add_p_values(out, observed, q, o, partners)
    return out


def _dyad_values(
    q: Quantities, pair: _Pair, o: MeasureOptions, details: dict[str, Any]
) -> dict[str, Any]:
    """Compute the untested measures of a pair, and its time-resolved details for the figures."""
    start, rate = details["start"], q.rate
    cc, lead = pair.co_confidence, pair.leadership
    sync = synchrony_episodes.find_synchrony_episodes(
        q.relative_phase, rate, o.sync_window, o.sync_threshold
    )
    details |= {"co_confidence": cc, "synchrony": sync}
    leader = None
    if lead is not None:
        details["leadership"] = lead
        leader, _ = lead.leader(rate, o.leader_share)
    segments = [
        {"start": s.start + start, "end": s.end + start, "dv": s.dv, "dt": s.dt}
        for s in cc.segments
    ]
    return {
        "co_confidence_count": len(cc.segments),
        "co_confidence_mean_length": cc.mean_length,
        "co_confidence_segments": segments,
        "synchrony_share": sync.share,
        "synchrony_entries": sync.entries,
        "synchrony_exits": sync.exits,
        "synchrony_mean_dwell": sync.mean_dwell,
        "synchrony_mean_gap": sync.mean_gap,
        "leader": "none" if leader is None else leader,
        "leader_lag_s": float("nan")
        if lead is None or leader is None
        else lead.leader_lag(leader, rate),
    }


def _add_influence(values: dict[str, Any], n_players: int) -> None:
    for i in range(n_players):
        outgoing = [values[f"transfer_entropy_{i}_to_{j}"] for j in range(n_players) if j != i]
        values[f"influence_player_{i}"] = float(np.mean(outgoing))


def _add_p_values(
    out: Measures, observed: dict[str, float], q: Quantities, o: MeasureOptions,
    partners: Sequence[Session],
) -> None:  # fmt: skip
    x, rate = q.positions, q.rate
    if o.surrogates == "shift" and x.shape[1] - 2 * round(o.min_shift * rate) < 1:
        out.values["surrogates"] = {"kind": o.surrogates, "n": 0, "min_shift": o.min_shift,
                                    "seed": o.seed, "note": "too short for the shifts"}  # fmt: skip
        out.notes.append(
            f"no p-values: {x.shape[1] / rate:g} s is too short for circular shifts of at "
            f"least --min-shift ({o.min_shift:g} s) from either end"
        )
        return
    directions = registry.measures_tested(x.shape[0])
    chunks = list(_surrogate_draws(q, o, partners))
    draws = {name: np.concatenate([[], *(chunk[name] for chunk in chunks)]) for name in directions}
    for name, greater in directions.items():
        null = np.asarray(draws[name], dtype=np.float64)
        out.null[name] = null
        out.values[registry.p_value_key(name)] = p_value(observed[name], null, greater)
    n = len(next(iter(draws.values())))
    out.values["surrogates"] = {
        "kind": o.surrogates, "n": n, "min_shift": o.min_shift, "seed": o.seed,
    }  # fmt: skip


def weak_null_of(quantities: Sequence[Quantities]) -> WeakNull | None:
    """Test the synchrony of sessions together (`surrogates.kuramoto_weak_null`).

    Returns
    -------
    WeakNull or None
        The test of the most common group size among the moving sessions of two or more
        players, when two or more have it, else None.
    """
    moving = [q for q in quantities if q.positions.shape[0] >= 2 and q.moving]
    sizes = [q.positions.shape[0] for q in moving]
    if not sizes:
        return None
    size = max(set(sizes), key=sizes.count)
    sample = [q.phases for q in moving if q.positions.shape[0] == size]
    return kuramoto_weak_null(sample) if len(sample) >= 2 else None
