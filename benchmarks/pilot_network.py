"""A protocol piloted under an emulated internet and without it, read side by side (issue 48).

Protocol (docs/lab.md, *Piloting under an emulated internet*):

- **Pilots**: ``examples/protocols/online.toml`` (following and leading a ``bundled:slow``
  avatar, one 20 s trial each, Latin square), participants 0-3, ``--seed 1``, stand-ins
  ``bundled:slow``; once straight to the server on loopback (LAB), once with ``--network
  80+-25`` (HOME). The same seed and participant numbers give both the same orders and stand-ins.
- **Tables and reports**: ``mirror-avatar study table DIR --out DIR/table`` and ``mirror-avatar
  study report DIR/table --protocol examples/protocols/online.toml --out DIR/report`` for each.
- **Read here**: each report's ``conditions.csv`` (mean over participants, 95 % bootstrap CI),
  its ``contrasts.csv`` (lead against follow, within participants), the tables' page columns
  (round trips of the stand-in pages' clock exchanges, on the persons' rows) and the proxy's
  truth (``pilot-network.csv``: each page chunk's drawn delay and how long it was held).

Run: ``python benchmarks/pilot_network.py LAB HOME`` after the four commands; prints Markdown.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

MEASURES = (
    "rmse", "phase_locking", "sd_relative_phase", "time_lag", "max_cross_correlation",
    "leader_share", "synchrony_share", "transfer_entropy_0_to_1", "transfer_entropy_1_to_0",
)  # fmt: skip
"""The measures compared (columns of the study table)."""

PAGE = ("page_rtt_median_ms", "page_rtt_p95_ms", "page_rtt_max_ms", "page_uncertainty_ms")
"""The page columns compared (ms)."""


def conditions(lab: Path, home: Path) -> list[str]:
    """Tabulate each measure and condition's mean [95 % CI] without and with the network."""
    read = [pd.read_csv(d / "report" / "conditions.csv").set_index(["measure", "condition"])
            for d in (lab, home)]  # fmt: skip
    lines = ["| measure | condition | without | with 80 +- 25 ms |", "|---|---|---|---|"]
    for (measure, condition), _ in read[0].loc[list(MEASURES)].iterrows():
        cells = [f"{r['mean']:.3g} [{r.ci_low:.3g}, {r.ci_high:.3g}]"
                 for r in (t.loc[(measure, condition)] for t in read)]  # fmt: skip
        lines.append(f"| {measure} | {condition} | {cells[0]} | {cells[1]} |")
    return lines


def pages(lab: Path, home: Path) -> list[str]:
    """Tabulate the persons' pages' round trips and clock uncertainty (mean of participants)."""
    lines = ["| pilot | condition | " + " | ".join(PAGE) + " |", "|---" * (2 + len(PAGE)) + "|"]
    for name, folder in (("without", lab), ("with 80 +- 25 ms", home)):
        rows = pd.read_csv(folder / "table" / "study.csv")
        means = rows[rows.player_kind == "person"].groupby("condition")[list(PAGE)].mean()
        for condition, row in means.iterrows():
            lines.append(f"| {name} | {condition} | " + " | ".join(f"{v:.1f}" for v in row) + " |")
    return lines


def contrasts(lab: Path, home: Path) -> list[str]:
    """Tabulate each pilot's lead-minus-follow difference (mixed model), its CI and p."""
    lines = ["| pilot | measure | lead - follow | 95 % CI | p |", "|---|---|---|---|---|"]
    for name, folder in (("without", lab), ("with 80 +- 25 ms", home)):
        table = pd.read_csv(folder / "report" / "contrasts.csv")
        for _, r in table[table.measure.isin(MEASURES)].iterrows():
            lines.append(f"| {name} | {r.measure} | {r.difference:+.3g} | "
                         f"{r.ci_low:.3g} to {r.ci_high:.3g} | {r.p:.3g} |")  # fmt: skip
    return lines


def truth(home: Path) -> list[str]:
    """Tabulate the emulated internet's truth for the pages: drawn and held delays (ms)."""
    log = pd.read_csv(home / "pilot-network.csv", keep_default_na=False)
    joined = log[log.request.str.startswith("GET /ws/join/sha256:")].connection.unique()
    chunks = log[log.connection.isin(joined) & (log.bytes > 0)]
    held = chunks.eval("delivered_s - received_s") * 1000.0
    lines = ["| direction | chunks | drawn mean / sd ms | held median / mean ms |",
             "|---|---|---|---|"]  # fmt: skip
    for direction in ("up", "down"):
        mine = chunks.direction == direction
        drawn = chunks[mine].delay_ms
        lines.append(f"| {direction} | {mine.sum()} | {drawn.mean():.1f} / {drawn.std():.1f} | "
                     f"{held[mine].median():.1f} / {held[mine].mean():.1f} |")  # fmt: skip
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("lab", type=Path, help="the pilot without the network")
    parser.add_argument("home", type=Path, help="the pilot with --network")
    args = parser.parse_args()
    for part in (conditions, pages, contrasts):
        print("\n".join(part(args.lab, args.home)), end="\n\n")
    print("\n".join(truth(args.home)))


if __name__ == "__main__":
    main()
