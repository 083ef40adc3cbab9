"""The command-line options of the field's measures, and their text table.

`measure_options` adds to a command one option per open parameter of
`mirror_avatar.metrics.measures.MeasureOptions` (each a **choice**, METHODS section 12), its
type and range built from the parameter's declared constraint, and
`options_from` turns the command's keyword arguments back into that record.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import fields
from typing import Any, TypeVar

import click

from mirror_avatar.cli.constrained import constrained_type, with_range
from mirror_avatar.metrics.measures import CONSTRAINTS, MeasureOptions
from mirror_avatar.report import p_text

F = TypeVar("F", bound=Callable[..., Any])

OPTIONS = (
    ("n_surrogates", "--surrogates", "Surrogates per session for the p-values (0: none)."),
    ("surrogates", "--surrogate-kind",
     "shift: circular shifts of the partners; pseudo: player 0 with other sessions' partners."),
    ("seed", "--surrogate-seed", "Seed of the surrogate draws (recorded)."),
    ("min_shift", "--min-shift", "Smallest circular shift (s)."),
    ("min_duration", "--cc-min-duration", "Shortest co-confidence segment (s)."),
    ("jitter_threshold", "--jitter-threshold",
     "Jitter index of the velocity difference above which motion is not smooth."),
    ("dv_threshold", "--dv-threshold", "Largest relative velocity difference of CC."),
    ("dv_window", "--dv-window", "Window of the velocity difference (s)."),
    ("rest_fraction", "--rest-fraction",
     "Share of the pair's RMS speed below which the pair rests (not CC)."),
    ("sync_threshold", "--sync-threshold", "Windowed CV of synchrony episodes."),
    ("sync_window", "--sync-window", "Window of the windowed CV (s)."),
    ("lead_signal", "--lead-signal", "Series the leadership windows correlate."),
    ("lead_window", "--lead-window", "Window of the lagged cross-correlation (s)."),
    ("lead_step", "--lead-step", "Step between windows (s)."),
    ("lead_max_lag", "--lead-max-lag", "Largest lag of the leadership search (s)."),
    ("lead_min_peak", "--lead-min-peak", "Smallest correlation of a picked peak."),
    ("leader_share", "--leader-share", "Share of windows a session's leader must lead."),
    ("te_bins", "--te-bins", "Equiprobable velocity bins of transfer entropy."),
    ("te_history", "--te-history", "Target history of transfer entropy (steps)."),
    ("te_step", "--te-step", "Time step of transfer entropy (s)."),
)  # fmt: skip
"""(field of MeasureOptions, option name, help); each option's type and range come from the
field's declaration, `mirror_avatar.metrics.measures.CONSTRAINTS`."""

DEFAULTS = {f.name: f.default for f in fields(MeasureOptions)}


def measure_options(command: F) -> F:
    """Add the measures' options (`OPTIONS`) to a click command, defaults and ranges shown."""
    for name, flag, text in reversed(OPTIONS):
        constraint = CONSTRAINTS[name]
        command = click.option(
            flag, name, type=constrained_type(constraint), default=DEFAULTS[name],
            show_default=True, help=with_range(text, constraint),
        )(command)  # fmt: skip
    return command


def options_from(kwargs: dict[str, Any]) -> MeasureOptions:
    """Take the measures' options out of a command's keyword arguments (removed from it)."""
    return MeasureOptions(**{name: kwargs.pop(name) for name, *_ in OPTIONS})


MEASURE_ROWS = (
    ("co_confidence_rate", "CC rate (share of time in co-confidence)", ""),
    ("co_confidence_count", "CC segments", ""),
    ("co_confidence_mean_length", "CC mean segment length", "s"),
    ("synchrony_share", "share of time in synchrony", ""),
    ("synchrony_entries", "entries into synchrony", ""),
    ("synchrony_mean_dwell", "mean dwell in synchrony", "s"),
    ("leader", "leader (windowed cross-correlation)", ""),
    ("leader_share", "share of windows the leader leads", ""),
    ("leader_lag_s", "leader's lag", "s"),
    ("leadership_strength", "leadership strength (mean peak correlation)", ""),
    ("group_synchronisation", "group synchronisation (rho_g)", ""),
)
"""(key, description, unit) of the measures printed for one session."""


FAMILIES = (("jitter_index_player_", ""), ("transfer_entropy_", "bits"), ("influence_", "bits"))
"""Key prefixes of the measures with one value per player or pair, and their units."""


def _family_label(key: str) -> str:
    if key.startswith("jitter_index_player_"):
        return f"jitter index player {key.rsplit('_', 1)[1]} (2-3 Hz share)"
    if key.startswith("transfer_entropy_"):
        source, target = key.removeprefix("transfer_entropy_").split("_to_")
        return f"transfer entropy {source} -> {target}"
    return key.replace("_", " ")


MISSING_WORDS = {
    "co_confidence_mean_length": "no segment",
    "synchrony_mean_dwell": "no episode",
    "leader_lag_s": "no leader",
    "leader_share": "no window",
    "leadership_strength": "no window",
}
"""What a measure without a value (NaN) is written as; any other: ``none``."""


def _shown(key: str, value: Any) -> tuple[str, bool]:
    """Return a measure's value as text, and whether it has one (NaN: `MISSING_WORDS`)."""
    if isinstance(value, str | int):
        return str(value), True
    if not math.isfinite(value):
        return MISSING_WORDS.get(key, "none"), False
    return f"{value:.4f}", True


def format_measures(values: dict[str, Any], options: MeasureOptions) -> str:
    """Render the measures of one session as aligned text, each tested one with its p-value.

    A measure without a value is written in words (`MISSING_WORDS`), never ``nan``; a p-value
    at the floor of the surrogates is written ``p <= 0.01`` (`mirror_avatar.report.p_text`);
    the seed printed is ``options.seed``, the one the report and ``metrics.json`` name (this
    session's surrogates are drawn from a child of it).
    """
    p_keys = {"max_cross_correlation": "time_lag_p_value"}
    rows = [row for row in MEASURE_ROWS if row[0] in values]
    rows += [(k, _family_label(k), unit) for k in values for prefix, unit in FAMILIES
             if k.startswith(prefix) and not k.endswith("_p_value")]  # fmt: skip
    if not rows:
        return ""
    if values.get("leader") == "none":
        rows = [_no_leader_row(row, options) for row in rows]
    n = int(values.get("surrogates", {}).get("n", options.n_surrogates))
    width = max(len(description) for _, description, _ in rows)
    lines = []
    for key, description, unit in rows:
        shown, present = _shown(key, values[key])
        p = values.get(p_keys.get(key, f"{key}_p_value"))
        tail = "" if p is None or not present else f"  {p_text(p, n)}"
        lines.append(f"{description:<{width}}  {shown:>8}  {unit if present else '':<4}{tail}")
    lines = [line.rstrip() for line in lines]
    tested = [("time_lag_p_value", "time lag (its cross-correlation peak)"),
              ("phase_locking_p_value", "CV against surrogates"),
              ("rmse_p_value", "RMSE against surrogates")]  # fmt: skip
    for key, label in tested:
        if key in values:
            lines.append(f"{label:<{width}}  {p_text(values[key], n)}")
    if "surrogates" in values:
        s = values["surrogates"]
        lines.append(f"({s['n']} {s['kind']} surrogates, --surrogate-seed {options.seed})")
    return "\n".join(lines)


def _no_leader_row(row: tuple[str, str, str], options: MeasureOptions) -> tuple[str, str, str]:
    """Word a row of a session without a leader so that it cannot be read as one's."""
    key, description, unit = row
    if key == "leader":
        return key, f"leader (none leads {options.leader_share:.0%} of the windows)", unit
    if key == "leader_share":
        return key, "share of windows the most-leading player leads", unit
    return row


def scalar_measures(values: dict[str, Any]) -> dict[str, Any]:
    """Keep the measures that fit a table cell (numbers, the leader), for the table of sessions."""
    return {k: v for k, v in values.items() if isinstance(v, int | float | str)}
