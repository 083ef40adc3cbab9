"""Zhai et al. (2017)'s Table 4, as published and in their own definitions.

Five people (HP, the human benchmark) and four models tracked one prerecorded reference signal
(Zhai et al., IEEE Trans Cybern 48:1018-1029, section 6.3.4, Table 4). Their values are shown
beside the benchmark's own tables, never in them: their reference signal is not our leaders, and
their CV is not our phase locking R (`CV_NOTE`; METHODS, "Benchmark").
"""

from __future__ import annotations

import pandas as pd

TABLE4 = {
    "HP": {"RPE": 0.0914, "CV": 0.3011, "TL (s)": 0.2035},
    "OPC": {"RPE": 0.0816, "CV": 0.1002, "TL (s)": 0.1274},
    "HKB": {"RPE": 2.1767, "CV": 0.9400, "TL (s)": 1.5192},
    "RPC": {"RPE": 0.3838, "CV": 0.7602, "TL (s)": 0.0428},
    "JKE": {"RPE": 0.1467, "CV": 0.4859, "TL (s)": -0.9674},
}
"""Table 4 by their player and their column, as printed: relative position error (units),
CV and time lag (s)."""

PLAYER_NAMES = {
    "HP": "the human benchmark (five people)",
    "OPC": "optimal-control virtual player (our vt)",
    "HKB": "HKB oscillator (our hkb)",
    "RPC": "reactive-predictive controller (our rpc)",
    "JKE": "Jirsa-Kelso excitator (our excitator)",
}
"""What each of their rows is, and the follower of ours built after it."""

CV_NOTE = (
    "Their CV is printed as they print it. Their preprint (arXiv 1509.05881) and their code "
    "(circularVariance.m, github.com/diBernardoGroup/MirrorGame) define it as "
    "R = |mean exp(i dphi)| of the relative phase, our phase locking; yet Table 4 "
    "behaves like the circular variance 1 - R: HKB, the worst tracker (RPE 2.18), has the "
    "highest CV (0.94) and the optimal-control player, the best, the lowest (0.10). Their CV is "
    "therefore not compared with our R."
)
"""Why their CV column and our phase locking R are never set side by side."""

CAPTION = (
    "Zhai et al. (2017), Table 4, as published: five people and four models tracking one "
    "prerecorded reference signal, in their definitions (not our leaders, not our measures)."
)
"""The heading of their table wherever it is shown."""


def published_table() -> pd.DataFrame:
    """Table 4 as a frame: one row per player of theirs, their columns and what the row is."""
    table = pd.DataFrame.from_dict(TABLE4, orient="index")
    table.insert(0, "player", [PLAYER_NAMES[name] for name in table.index])
    table.index.name = "Zhai et al."
    return table
