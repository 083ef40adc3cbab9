"""The one vocabulary of a session's measures: each one's key, words, unit and test.

Every number `mirror_avatar.metrics.summary.session_metrics` and
`mirror_avatar.metrics.measures.session_measures` return is declared here once, as a `Measure`:
its key (the raw name ``metrics.json``, ``sessions.csv`` and the study table keep), a label in
words and its unit (what reports, the command line and the study's data dictionary show), the
direction of its test against surrogates and the key of its p-value, whether it heads a
session's summary, and the figure of ``evaluate``'s report that draws it. A measure with one
value per player or ordered pair of players has a key with ``{i}`` (and ``{j}``):
``jitter_index_player_{i}``, ``transfer_entropy_{i}_to_{j}``.

The order of `MEASURES` is the order they are shown and tested in: the tested measures of a
pair or a group (`measures_tested`), and the headline columns (`HEADLINE`), follow it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache
from typing import Literal

from mirror_avatar.metrics.jitter import JITTER_BAND

Players = Literal["pair", "group", "any"]

BAND = f"{JITTER_BAND[0]:g}-{JITTER_BAND[1]:g} Hz"
"""The jitter band in words (`mirror_avatar.metrics.jitter.JITTER_BAND`)."""

UNIT_NAMES = {"units": "playing range units"}
"""Units written in full where a unit stands alone (the study's data dictionary)."""


@dataclass(frozen=True)
class Measure:
    """One measure of a session.

    Attributes
    ----------
    key
        Its key in ``metrics.json`` and column in ``sessions.csv``; ``{i}`` and ``{j}`` stand
        for players' indices.
    label
        Its name in words, as a report's column or the command line's row shows it (``{i}``,
        ``{j}`` as in ``key``).
    unit
        ``"units"`` (playing range units), ``"s"``, ``"rad"``, ``"bits"``, or ``""`` (none).
    description
        One sentence of what it is, for the study's data dictionary.
    greater
        The direction of its test against surrogates: True when a larger value is more
        coordinated, False when a smaller one is (RMS); None when it is not tested.
    players
        The sessions it is tested in: ``"pair"``, ``"group"`` (three or more) or ``"any"``.
    p_value
        The key of its p-value, when not ``<key>_p_value``.
    headline
        Whether it heads a session's summary: the columns of ``evaluate``'s table of sessions
        and report, the lab console's list of a trial.
    figure
        The figure of each session in ``evaluate``'s report that draws it, or ``""``.
    missing
        How it is written when it has no value (NaN), never ``nan``.
    symbol
        Its short name in a narrow column (``CV``, ``rho_k``), or ``""`` (use ``label``).
    in_table
        Whether it is a column of the study table (`TABLE_COLUMNS`); a value per player is the
        player's own column, on its row.
    group_player
        Whether a group has one value per player (the player against its neighbours' mean, or to
        the group), on the player's row (`GROUP_PLAYER`).
    end_screen
        Whether a participant's end screen shows it after a trial (`END_SCREEN`).
    metric
        Whether `mirror_avatar.metrics.summary.session_metrics` computes it (the others are
        `mirror_avatar.metrics.measures.session_measures`'s).
    angle
        Whether its values are directions on the circle (a mean phase, not a spread in
        radians): a study averages and compares them by circular statistics.
    """

    key: str
    label: str
    unit: str
    description: str
    greater: bool | None = None
    players: Players = "any"
    p_value: str = ""
    headline: bool = False
    figure: str = ""
    missing: str = "none"
    symbol: str = ""
    in_table: bool = True
    group_player: bool = False
    end_screen: bool = False
    metric: bool = False
    angle: bool = False

    def p_value_key(self, **indices: int) -> str:
        """Return the key of its p-value against surrogates (players' indices as ``i``, ``j``)."""
        return self.p_value or f"{self.key.format(**indices)}_p_value"


MEASURES: tuple[Measure, ...] = (
    Measure("phase_locking", "CV (phase locking, 0-1)", "",
            "Phase locking, the mean resultant length of the relative phase (the field's CV; 1: "
            "phase locked; a group: against the neighbours' mean)",
            greater=True, players="pair", headline=True, figure="surrogates", symbol="CV",
            group_player=True, end_screen=True, metric=True),
    Measure("rmse", "RMSE", "units",
            "RMS of the difference of the two players' positions (a group: of the player's "
            "against its neighbours' mean)",
            greater=False, players="pair", headline=True, figure="surrogates", symbol="RMSE",
            group_player=True, end_screen=True, metric=True),
    Measure("mean_relative_phase", "mean relative phase (player 0 - player 1)", "rad",
            "Circular mean of the relative phase, player 0 minus player 1", headline=True,
            figure="relative phase", metric=True, angle=True),
    Measure("sd_relative_phase", "circular SD of relative phase", "rad",
            "Circular SD of the relative phase", figure="relative phase", metric=True),
    Measure("time_lag", "time lag (player 0 ahead > 0)", "s",
            "Time lag at the cross-correlation peak, positive when player 0 leads (a group: the "
            "player against its neighbours' mean)", headline=True, symbol="lag",
            group_player=True, metric=True),
    Measure("max_cross_correlation", "peak cross-correlation", "",
            "Peak of the cross-correlation of the positions", greater=True, players="pair",
            p_value="time_lag_p_value", figure="surrogates", symbol="xcorr",
            group_player=True, metric=True),
    Measure("emd_players", "EMD between the players' IMS", "",
            "EMD between the two players' velocity IMS", metric=True),
    Measure("emd_reference_{i}", "EMD player {i} to its reference IMS", "",
            "EMD between the player's velocity IMS and its reference velocities' IMS",
            in_table=False, metric=True),
    Measure("emd_target_{i}", "EMD player {i} to its target's IMS (cyber player)", "",
            "EMD between the cyber player's velocity IMS and its target's",
            in_table=False, metric=True),
    Measure("jitter_index_player_{i}", f"jitter index player {{i}} ({BAND} share)", "",
            "The player's jitter index: share of velocity power in the jitter band",
            headline=True, figure="timeline"),
    Measure("co_confidence_rate", "CC rate (share of time in co-confidence)", "",
            "Share of the trial in co-confidence (moving together smoothly)", greater=True,
            players="pair", headline=True, figure="timeline"),
    Measure("co_confidence_count", "CC segments", "", "Co-confidence segments",
            headline=True, figure="timeline"),
    Measure("co_confidence_mean_length", "CC mean segment length", "s",
            "Mean length of the co-confidence segments", figure="timeline", missing="no segment"),
    Measure("co_confidence_segments", "CC segments (start, end, dV, dt)", "s",
            "Each co-confidence segment: start and end in session time, dV and dt",
            figure="timeline", in_table=False),
    Measure("synchrony_share", "share of time in synchrony", "",
            "Share of the trial in synchrony episodes"),
    Measure("synchrony_entries", "entries into synchrony", "", "Entries into synchrony"),
    Measure("synchrony_exits", "exits from synchrony", "", "Exits from synchrony"),
    Measure("synchrony_mean_dwell", "mean dwell in synchrony", "s", "Mean dwell in synchrony",
            missing="no episode"),
    Measure("synchrony_mean_gap", "mean gap between synchrony episodes", "s",
            "Mean gap between synchrony episodes", missing="no gap"),
    Measure("leader", "leader (windowed cross-correlation)", "",
            "Label of the player who led (windowed cross-correlation), none if neither",
            headline=True, figure="leadership"),
    Measure("leadership_strength", "leadership strength (mean peak correlation)", "",
            "Mean picked peak of the windowed cross-correlation", greater=True, players="pair",
            figure="leadership", missing="no window"),
    Measure("leader_share", "share of windows the leader leads", "",
            "Share of windows the leader leads", greater=True, players="pair",
            headline=True, figure="leadership", missing="no window"),
    Measure("leader_lag_s", "leader's lag", "s", "The leader's lag", headline=True,
            figure="leadership", missing="no leader"),
    Measure("group_synchronisation", "group synchronisation (rho_g)", "",
            "Group synchronisation, time mean of rho_g", greater=True, players="group",
            headline=True, figure="group synchronisation", end_screen=True, metric=True),
    Measure("group_synchronisation_sd", "SD of group synchronisation", "",
            "SD over time of rho_g", figure="group synchronisation", metric=True),
    Measure("kuramoto_order", "Kuramoto order parameter r", "",
            "Time mean of the Kuramoto order parameter r", headline=True, metric=True),
    Measure("synchronisation", "synchronisation to the group (rho_k)", "",
            "The player's synchronisation to the group, rho_k", symbol="rho_k",
            group_player=True, end_screen=True, metric=True),
    Measure("relative_phase_to_group", "mean phase relative to the group", "rad",
            "The player's mean phase relative to the group", symbol="phase",
            group_player=True, metric=True, angle=True),
    Measure("mean_phase_locking", "mean CV to the neighbours", "",
            "Mean over the players of their phase locking to their neighbours", headline=True,
            metric=True),
    Measure("mean_rmse", "mean RMSE to the neighbours", "units",
            "Mean over the players of their RMS against their neighbours", headline=True,
            metric=True),
    Measure("transfer_entropy_{i}_to_{j}", "transfer entropy {i} -> {j}", "bits",
            "Transfer entropy from player {i}'s velocity to player {j}'s", greater=True,
            headline=True, figure="surrogates"),
    Measure("influence_player_{i}", "influence of player {i} (mean TE to the others)", "bits",
            "The player's influence: mean transfer entropy to the others", headline=True),
)  # fmt: skip
"""Every measure, in the order they are shown and tested."""

HEADLINE = tuple(m.key for m in MEASURES if m.headline)
"""The keys that head a session's summary, in order (``{i}``, ``{j}``: one per player or pair)."""

GROUP_PLAYER = tuple(m.key for m in MEASURES if m.group_player)
"""The keys a group has one value of per player, on the player's row, in order."""

END_SCREEN = tuple(m.key for m in MEASURES if m.end_screen)
"""The keys a participant's end screen shows, in order (a group's own ones on the player's row)."""

OWN_SUFFIX = "_player_{i}"
"""The end of the key of a measure with one value per player, left out of its table column."""


def _table_columns(measure: Measure) -> tuple[str, ...]:
    """Name a measure's columns in the study table: a pair's both ways, a player's own."""
    if "{j}" in measure.key:
        return (measure.key.format(i=0, j=1), measure.key.format(i=1, j=0))
    return (measure.key.removesuffix(OWN_SUFFIX),)


TABLE_COLUMNS = tuple(c for m in MEASURES if m.in_table for c in _table_columns(m))
"""The measure columns of the study table, in order: keys, a player's own without
``_player_{i}`` (`OWN_COLUMNS`), a pair's measure for players 0 and 1 both ways."""

OWN_COLUMNS = tuple(
    m.key.removesuffix(OWN_SUFFIX) for m in MEASURES if m.in_table and m.key.endswith(OWN_SUFFIX)
)
"""The table columns of a measure with one value per player: the player's own, on its row."""


@cache
def _patterns() -> list[tuple[re.Pattern[str], Measure]]:
    return [
        (re.compile(re.escape(m.key).replace(r"\{i\}", r"(?P<i>\d+)").replace(r"\{j\}",
                                                                              r"(?P<j>\d+)")), m)
        for m in MEASURES
    ]  # fmt: skip


def find(key: str) -> tuple[Measure, dict[str, int]] | None:
    """Return the measure a key names and its players' indices, or None for another key."""
    for pattern, measure in _patterns():
        found = pattern.fullmatch(key)
        if found:
            return measure, {name: int(value) for name, value in found.groupdict().items()}
    return None


def registry_order(key: str) -> tuple[int, tuple[int, ...]]:
    """Sort key of a measure's key: its measure's place in `MEASURES`, then its players."""
    found = find(key)
    if found is None:
        raise KeyError(key)
    return MEASURES.index(found[0]), tuple(found[1].values())


def is_metric(key: str) -> bool:
    """Whether a key names a number of `mirror_avatar.metrics.summary.session_metrics`."""
    found = find(key)
    return found is not None and found[0].metric


def is_headline(key: str) -> bool:
    """Whether a key names a measure that heads a session's summary."""
    found = find(key)
    return found is not None and found[0].headline


def measure(key: str) -> Measure:
    """Return the measure a key names.

    Raises
    ------
    KeyError
        A key no measure has.
    """
    found = find(key)
    if found is None:
        raise KeyError(key)
    return found[0]


def label(key: str) -> str:
    """Return a key's label in words (``transfer_entropy_0_to_1``: ``transfer entropy 0 -> 1``)."""
    found = find(key)
    if found is None:
        raise KeyError(key)
    return found[0].label.format(**found[1])


def description(key: str) -> str:
    """Return a key's description, its players' indices filled in."""
    found = find(key)
    if found is None:
        raise KeyError(key)
    return found[0].description.format(**found[1])


def symbol(key: str) -> str:
    """Return a key's short name for a narrow column (its label when it has none)."""
    return measure(key).symbol or label(key)


def heading(key: str) -> str:
    """Return a key's label with its unit, as a report's column shows it: ``RMSE (units)``."""
    unit = measure(key).unit
    return f"{label(key)} ({unit})" if unit else label(key)


def p_value_key(key: str) -> str:
    """Return the key of the p-value of a tested measure's key."""
    found = find(key)
    if found is None:
        raise KeyError(key)
    return found[0].p_value_key(**found[1])


def tested_of(p_key: str) -> str | None:
    """Return the key of the measure a p-value's key belongs to, or None for another key."""
    if not p_key.endswith("_p_value"):
        return None
    named = {m.p_value: m.key for m in MEASURES if m.p_value}
    key = named.get(p_key, p_key.removesuffix("_p_value"))
    found = find(key)
    return key if found is not None and found[0].greater is not None else None


def measures_tested(n_players: int) -> dict[str, bool]:
    """Name the measures of ``n_players`` (two or more) tested against surrogates.

    Returns
    -------
    dict
        Key -> the direction of its test (True: larger is more coordinated), in the order of
        `MEASURES`; a measure of each ordered pair once per pair.
    """
    kind = "pair" if n_players == 2 else "group"
    pairs = [(i, j) for i in range(n_players) for j in range(n_players) if i != j]
    out: dict[str, bool] = {}
    for m in MEASURES:
        if m.greater is None or m.players not in (kind, "any"):
            continue
        keys = [m.key.format(i=i, j=j) for i, j in pairs] if "{j}" in m.key else [m.key]
        out |= dict.fromkeys(keys, m.greater)
    return out
