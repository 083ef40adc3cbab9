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
  means), each predicted draw against the sample it was predicted from (the view files of the
  complete trials, draw by draw), the report's
  ``conditions.csv`` and ``contrasts.csv``, and the proxy's truth (`pilot_network.truth`).

Run: ``python benchmarks/pilot_views.py PILOT`` after the three commands; prints Markdown.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd
from pilot_network import MEASURES, truth

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


def predicted_draws(pilot: Path) -> list[str]:
    """Tabulate the predicted trials' draws: RMS error (units) as drawn and as sampled.

    Each draw of a predicted trial against the partner's recorded position at the draw's time,
    as drawn (predicted) and as the sample it was predicted from would have been (linear between
    the recorded samples).
    """
    errors: dict[str, list[tuple[float, float]]] = {}
    for sidecar in sorted(pilot.glob("*-p*/trial-*_session.json")):
        metadata = json.loads(sidecar.read_text())["metadata"]
        if metadata["lab"]["partner_view"]["handling"] != "predicted" or not metadata["complete"]:
            continue
        stem = sidecar.name.removesuffix("_session.json")
        clock = pd.read_csv(sidecar.with_name(f"{stem}_inputs.csv")).clock_s.to_numpy()
        positions = pd.read_csv(sidecar.with_name(f"{stem}_session.csv"))
        view = pd.read_csv(sidecar.with_name(f"{stem}_view.csv"))
        for (person, other), seen in view.groupby(["label", "partner"]):
            partner = positions[f"position_{PLAYERS.index(str(other))}"].to_numpy()
            now = np.interp(seen.shown_s, clock, partner)
            sampled = np.interp(seen.sample_s, clock, partner)
            errors.setdefault(str(person), []).append(
                (float(np.sqrt(np.mean((seen.x - now) ** 2))),
                 float(np.sqrt(np.mean((sampled - now) ** 2))))
            )  # fmt: skip
    lines = ["| person | trials | predicted (drawn) | as sampled | trials nearer predicted |",
             "|---|---|---|---|---|"]  # fmt: skip
    for person, pairs in sorted(errors.items()):
        drawn, sampled = np.array(pairs).T
        lines.append(f"| {person} | {len(pairs)} | {drawn.mean():.4f} | {sampled.mean():.4f} | "
                     f"{int(np.sum(drawn < sampled))} |")  # fmt: skip
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
    parts = (views, predicted_draws, conditions, contrasts, truth)
    print("\n\n".join("\n".join(part(pilot)) for part in parts))


if __name__ == "__main__":
    main()
