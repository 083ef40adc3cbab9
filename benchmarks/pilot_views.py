"""Three delay handlings piloted under an emulated internet, read from a pilot's table (issue 49).

Protocol (docs/lab.md, *Partners across links of different delays*):

- **Pilot**: ``examples/protocols/delay_handling.toml`` (P1 leads, P2 follows; ``as_arrives``,
  ``equalised``, ``predicted``, 3 trials of 10 s each, Latin square), participants 0-5, stand-ins
  ``bundled:slow``, ``--network 120+-40``, into PILOT.
- **Table and report**: ``mirror-avatar study table PILOT --out PILOT/table`` and
  ``mirror-avatar study report PILOT/table --protocol examples/protocols/delay_handling.toml
  --out PILOT/report``.
- **Read here**: what each person's page drew under each handling (the table's ``page_view_*``
  and ``page_rtt_median_ms``, persons' rows of the complete trials: mean of the participants'
  means), each predicted draw against the sample it was predicted from and replayed with the
  partner's samples fitted at their read times (the server's fit) and at the control ticks that
  recorded them (the view, pointer and inputs files of the complete trials, draw by draw), the
  share of ticks that held a person's previous position, how predictable each person's reads
  are without a network (`on_reads`), the report's ``conditions.csv`` and ``contrasts.csv``,
  and the proxy's truth (`pilot_network.truth`).

Run: ``python benchmarks/pilot_views.py PILOT`` after the three commands; prints Markdown.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd
from pilot_network import MEASURES, truth

from mirror_avatar.dynamics import CONTROL_PERIOD
from mirror_avatar.files.trials import PLAYING_RANGE
from mirror_avatar.lab.running.partner_frames import FIT_TICKS
from mirror_avatar.realtime.partner_view import FIT_WINDOW_S, dead_reckon, recorded_read_s

VIEW = ("page_view_delay_ms", "page_view_delay_p95_ms", "page_view_error_rms", "page_rtt_median_ms")
"""The page columns read per handling and person."""

COMPARED = (*MEASURES, "emd_players")
"""The measures compared (columns of the study table)."""

PLAYERS = ("P1", "P2")
"""The protocol's players, in slot order (the recording's ``position_0``, ``position_1``)."""


def views(pilot: Path) -> list[str]:
    """Tabulate each handling and person's view: delays (ms), error (units), round trip (ms)."""
    rows = pd.read_csv(pilot / "table" / "study.csv")
    people = rows[(rows.player_kind == "person") & rows.complete]
    per_participant = people.groupby(["partner_view", "person", "participant"])[list(VIEW)].mean()
    means = per_participant.groupby(["partner_view", "person"]).mean()
    lines = ["| handling | person | " + " | ".join(VIEW) + " |", "|---" * (2 + len(VIEW)) + "|"]
    for (handling, person), row in means.iterrows():
        cells = [f"{row[c]:.4f}" if c.endswith("rms") else f"{row[c]:.1f}" for c in VIEW]
        lines.append(f"| {handling} | {person} | " + " | ".join(cells) + " |")
    return lines


def replay(
    clock: np.ndarray, partner: np.ndarray, reads: pd.DataFrame, ks: np.ndarray, horizon: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """Return a partner's draws at samples ``ks`` predicted from its reads and from its ticks.

    ``clock`` (s) and ``partner`` (units) are the recording's ticks, ``reads`` the partner's
    pointer samples, ``horizon`` (s) the page's one-way delay. From the reads: those that
    arrived within the `FIT_TICKS` ticks up to each sample, at their read times (the server's
    fit). From the ticks: the positions of the ticks within `FIT_WINDOW_S` of it, at the
    ticks' times (the server's fit before it read the pointer samples' times). Also how far
    (s) the reads were extrapolated past the newest, on average.
    """
    read, x, arrived = (reads[c].to_numpy() for c in ("server_s", "x", "received_s"))
    back = round(FIT_WINDOW_S / CONTROL_PERIOD)
    from_reads, from_ticks, ahead = [], [], []
    for k in ks:
        known = (arrived <= clock[k]) & (arrived > clock[max(0, k - FIT_TICKS)])
        if known.any():
            to_s = recorded_read_s(clock[k] + horizon, read[known], arrived[known])
            from_reads.append(dead_reckon(read[known], x[known], to_s, PLAYING_RANGE))
            ahead.append(to_s - read[known][-1])
        else:
            from_reads.append(partner[k])
        ticks = slice(max(0, k - back), k + 1)
        from_ticks.append(dead_reckon(clock[ticks], partner[ticks], clock[k] + horizon,
                                      PLAYING_RANGE))  # fmt: skip
    return np.array(from_reads), np.array(from_ticks), float(np.mean(ahead))


def predicted_draws(pilot: Path) -> list[str]:
    """Tabulate the predicted trials' draws: RMS error (units) as drawn, replayed and as sampled.

    Each draw of a predicted trial against the partner's recorded position at the draw's time,
    as drawn, as `replay` predicts it from the partner's reads and from its ticks over half the
    page's median round trip, and as the sample it was predicted from would have been (linear
    between the recorded samples); with the share of the partner's ticks that held its previous
    position, the horizon (s) and how far the reads were extrapolated (s; `replay`).
    """
    errors: dict[str, list[tuple[float, ...]]] = {}
    for sidecar in sorted(pilot.glob("*-p*/trial-*_session.json")):
        metadata = json.loads(sidecar.read_text())["metadata"]
        if metadata["lab"]["partner_view"]["handling"] != "predicted" or not metadata["complete"]:
            continue
        stem = sidecar.name.removesuffix("_session.json")
        inputs = pd.read_csv(sidecar.with_name(f"{stem}_inputs.csv"))
        clock = inputs.clock_s.to_numpy()
        positions = pd.read_csv(sidecar.with_name(f"{stem}_session.csv"))
        view = pd.read_csv(sidecar.with_name(f"{stem}_view.csv"))
        pointer = pd.read_csv(sidecar.with_name(f"{stem}_pointer.csv")).dropna()
        for (person, other), seen in view.groupby(["label", "partner"]):
            partner = positions[f"position_{PLAYERS.index(str(other))}"].to_numpy()
            now = np.interp(seen.shown_s, clock, partner)
            horizon = metadata["pages"][person]["rtt_ms"]["median"] / 2000.0
            reads = pointer[pointer.label == other]
            *replayed, ahead = replay(clock, partner, reads, seen.k.to_numpy(), horizon)
            drawn = (seen.x.to_numpy(), *replayed, np.interp(seen.sample_s, clock, partner))
            rms = [float(np.sqrt(np.mean((x - now) ** 2))) for x in drawn]
            held = inputs[f"held_{other}"].mean()
            errors.setdefault(str(person), []).append((*rms, held, horizon, ahead))
    lines = ["| person | trials | predicted (drawn) | replayed: reads | replayed: ticks | "
             "as sampled | trials nearer predicted | partner's ticks held | horizon (s) | "
             "reads extrapolated (s) |", "|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for person, rows in sorted(errors.items()):
        drawn, reads, ticks, sampled, held, horizon, ahead = np.array(rows).T
        lines.append(f"| {person} | {len(rows)} | {drawn.mean():.4f} | {reads.mean():.4f} | "
                     f"{ticks.mean():.4f} | {sampled.mean():.4f} | "
                     f"{int(np.sum(drawn < sampled))} | {held.mean():.2f} | "
                     f"{horizon.mean():.3f} | {ahead.mean():.3f} |")  # fmt: skip
    return lines


HORIZONS_S = (0.05, 0.1, 0.15, 0.2, 0.3)
"""Horizons (s) a person's own reads are predicted over in `on_reads`."""


def on_reads(pilot: Path) -> list[str]:
    """Tabulate how predictable each person's motion is: RMS error (units) per horizon.

    From every third pointer sample of the complete trials (after the first ten): the position
    read a horizon later (linear between reads) against the sample held and against the sample
    extrapolated along the fit of the reads before it (`dead_reckon`): prediction without a
    network.
    """
    errors: dict[tuple[str, float], list[tuple[float, float]]] = {}
    for sidecar in sorted(pilot.glob("*-p*/trial-*_session.json")):
        if not json.loads(sidecar.read_text())["metadata"]["complete"]:
            continue
        stem = sidecar.name.removesuffix("_session.json")
        pointer = pd.read_csv(sidecar.with_name(f"{stem}_pointer.csv")).dropna()
        for person, reads in pointer.groupby("label"):
            t, x = reads.server_s.to_numpy(), reads.x.to_numpy()
            at = range(10, int(np.searchsorted(t, t[-1] - max(HORIZONS_S))), 3)
            for horizon in HORIZONS_S:
                later = np.interp(t[list(at)] + horizon, t, x)
                ahead = [dead_reckon(t[: i + 1], x[: i + 1], t[i] + horizon, PLAYING_RANGE)
                         for i in at]  # fmt: skip
                errors.setdefault((str(person), horizon), []).append(
                    (float(np.sqrt(np.mean((x[list(at)] - later) ** 2))),
                     float(np.sqrt(np.mean((np.array(ahead) - later) ** 2))))
                )  # fmt: skip
    lines = ["| person | horizon (s) | held | extrapolated |", "|---|---|---|---|"]
    for (person, horizon), pairs in sorted(errors.items()):
        held, ahead = np.array(pairs).mean(axis=0)
        lines.append(f"| {person} | {horizon} | {held:.4f} | {ahead:.4f} |")
    return lines


def conditions(pilot: Path) -> list[str]:
    """Tabulate each measure and handling's mean [95 % CI] (the report's conditions.csv)."""
    table = pd.read_csv(pilot / "report" / "conditions.csv").set_index(["measure", "condition"])
    lines = ["| measure | as_arrives | equalised | predicted |", "|---|---|---|---|"]
    for measure in COMPARED:
        if measure not in table.index.get_level_values(0):
            continue
        cells = [f"{r['mean']:.3g} [{r.ci_low:.3g}, {r.ci_high:.3g}]"
                 for r in (table.loc[(measure, c)] for c in ("as_arrives", "equalised",
                                                             "predicted"))]  # fmt: skip
        lines.append(f"| {measure} | " + " | ".join(cells) + " |")
    return lines


def contrasts(pilot: Path) -> list[str]:
    """Tabulate each handling against as_arrives: the mixed model's and the paired tests'.

    The difference, its CI and p are the mixed model's (``contrasts.csv``); ``converged`` says
    whether its fit converged (``results.json``: else its p is not reliable); ``t_p`` and
    ``wilcoxon_p`` are the paired t-test's and Wilcoxon's on the participants' means.
    """
    table = pd.read_csv(pilot / "report" / "contrasts.csv")
    models = json.loads((pilot / "report" / "results.json").read_text())["models"]
    converged = {m["measure"]: m["converged"] for m in models}
    rows = table[table.measure.isin(COMPARED)].itertuples()
    header = (
        "| measure | condition | difference | 95 % CI | p (converged) | paired t p | Wilcoxon p |"
    )
    return [header,
            "|---|---|---|---|---|---|---|",
            *(f"| {r.measure} | {r.condition} | {r.difference:+.3g} | {r.ci_low:.3g} to "
              f"{r.ci_high:.3g} | {r.p:.3g} ({'yes' if converged[r.measure] else 'no'}) | "
              f"{r.t_p:.3g} | {r.wilcoxon_p:.3g} |" for r in rows)]  # fmt: skip


def main() -> None:
    """Print every table of the pilot folder named on the command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pilot", type=Path, help="the pilot's folder (its table/ and report/)")
    pilot = parser.parse_args().pilot
    parts = (views, predicted_draws, on_reads, conditions, contrasts, truth)
    print("\n\n".join("\n".join(part(pilot)) for part in parts))


if __name__ == "__main__":
    main()
