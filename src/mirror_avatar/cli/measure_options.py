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
from mirror_avatar.metrics import registry
from mirror_avatar.metrics.measures import CONSTRAINTS, MeasureOptions
from mirror_avatar.signatures.permutations import p_text

F = TypeVar("F", bound=Callable[..., Any])

OPTIONS = (
    ("n_surrogates", "--surrogates", "Surrogates per session for the p-values (0: none)."),
    ("surrogates", "--surrogate-kind",
     "shift: circular shifts of the partners; pseudo: player 0 with other sessions' partners."),
    ("seed", "--surrogate-seed", "Seed of the surrogate draws of sessions that record none "
     "(recorded)."),
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
    "co_confidence_rate", "co_confidence_count", "co_confidence_mean_length", "synchrony_share",
    "synchrony_entries", "synchrony_mean_dwell", "leader", "leader_share", "leader_lag_s",
    "leadership_strength", "group_synchronisation",
)  # fmt: skip
"""The measures printed for one session, in order, besides those of each player or pair;
their words and units are `mirror_avatar.metrics.registry`'s."""

FAMILIES = ("jitter_index_player_", "transfer_entropy_", "influence_")
"""Key prefixes of the measures with one value per player or pair."""


def _shown(key: str, value: Any) -> tuple[str, bool]:
    """Return a measure's value as text, and whether it has one (NaN: its ``missing`` words)."""
    if isinstance(value, str | int):
        return str(value), True
    if not math.isfinite(value):
        return registry.measure(key).missing, False
    return f"{value:.4f}", True


def format_measures(values: dict[str, Any], options: MeasureOptions) -> str:
    """Render the measures of one session as aligned text, each tested one with its p-value.

    Words and units are the registry's (`mirror_avatar.metrics.registry`); a measure without a
    value is written in its ``missing`` words, never ``nan``; a p-value at the floor of the
    surrogates is written ``p <= 0.01`` (`mirror_avatar.signatures.permutations.p_text`);
    the seed printed is ``options.seed``, the one the report names (this session's
    surrogates are drawn from a child of it, or from the seed the session records:
    `mirror_avatar.metrics.measuring`; ``metrics.json`` names the seed drawn from).
    """
    keys = [key for key in MEASURE_ROWS if key in values]
    keys += [k for k in values if k.startswith(FAMILIES) and not k.endswith("_p_value")]
    rows = [(key, registry.label(key), registry.measure(key).unit) for key in keys]
    if not rows:
        return ""
    if values.get("leader") == "none":
        rows = [_no_leader_row(row, options) for row in rows]
    n = int(values.get("surrogates", {}).get("n", options.n_surrogates))
    width = max(len(description) for _, description, _ in rows)
    lines = []
    for key, description, unit in rows:
        shown, present = _shown(key, values[key])
        p = values.get(registry.p_value_key(key))
        tail = "" if p is None or not present else f"  {p_text(p, n)}"
        lines.append(f"{description:<{width}}  {shown:>8}  {unit if present else '':<4}{tail}")
    lines = [line.rstrip() for line in lines]
    printed = set(keys)
    for p_key, p in values.items():
        tested = registry.tested_of(p_key)
        if tested is not None and tested not in printed:
            text = f"{registry.label(tested)} against surrogates"
            lines.append(f"{text:<{width}}  {p_text(p, n)}")
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
