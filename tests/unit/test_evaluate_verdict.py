"""The verdict evaluate's report leads with: sessions beyond chance, in words, never overstated."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mirror_avatar.cli.evaluate_report import Evaluated, glance_tables, verdict
from mirror_avatar.metrics.measures import Measures
from mirror_avatar.sessions.session import Session


def evaluated(name: str, p: float, n: int, players: int = 2) -> Evaluated:
    """A session whose deciding measure has p-value ``p`` against ``n`` shift surrogates."""
    x = np.zeros((players, 10))
    session = Session(np.arange(10) / 10, x, x, x, np.full_like(x, np.nan))
    key = "phase_locking" if players == 2 else "group_synchronisation"
    metrics = {key: 0.8, "rmse": 0.1} if players == 2 else {key: 0.8}
    values = {key: 0.8, f"{key}_p_value": p, "surrogates": {"kind": "shift", "n": n}}
    return Evaluated(Path(f"/data/{name}.csv"), 12.0, session, metrics, Measures(values=values))


def test_one_session_beyond_chance_says_which_measure_and_how_surely():
    line = verdict([evaluated("pair", 0.01, 99)])
    assert line == ("pair.csv: coordinated beyond chance (CV (phase locking, 0-1) 0.80, "
                    "p <= 0.01 against 99 shift surrogates).")  # fmt: skip


def test_several_sessions_count_those_beyond_chance_pairs_and_groups_alike():
    found = [evaluated("a", 0.01, 99), evaluated("b", 0.3, 99), evaluated("g", 0.02, 99, 3)]
    line = verdict(found)
    assert line.startswith("2 of the 3 sessions tested are coordinated beyond chance")
    assert line.endswith(": a.csv, g.csv.")
    assert "p < 0.05 against 99 shift surrogates" in line
    assert list(glance_tables(found)) == ["Pairs", "Groups of 3"]


def test_p_at_0_05_does_not_beat_chance():
    assert verdict([evaluated("a", 0.05, 99), evaluated("b", 0.2, 99)]).startswith(
        "None of the 2 sessions tested beats chance"
    )


def test_too_few_surrogates_give_no_verdict_and_say_how_many_to_draw():
    line = verdict([evaluated("a", 0.05, 19)])
    assert line.startswith("No verdict on chance: 19 surrogates cannot give a p-value below 0.05")
    assert "--surrogates 99" in line
    table = glance_tables([evaluated("a", 0.05, 19)])["Pairs"]
    assert table["verdict"].tolist() == ["too few surrogates"]


def test_no_surrogates_no_verdict():
    assert verdict([evaluated("a", float("nan"), 0)]).startswith("No verdict on chance: no session")
