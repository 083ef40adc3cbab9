"""Synthetic study tables with known truth, in the schema of `mirror-avatar study table`.

Each participant (a person) plays every condition in a block, in a counterbalanced order (half
the participants in each order), with an avatar partner whose rows carry values far from any
person's so that a statistic that kept them would show it. A measure is a participant's level
(their random intercept), plus the condition's true effect, plus an order effect per position,
plus trial noise.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

CONDITIONS = ("no delay", "delay 0.5 s")
BASE = {"rms": 0.12, "phase_locking": 0.8}
PARTICIPANT_SD = {"rms": 0.03, "phase_locking": 0.05}
TRIAL_SD = {"rms": 0.02, "phase_locking": 0.04}
UNITS = {"rms": "units", "phase_locking": "1"}
AVATAR_VALUE = 100.0


def make_study_rows(
    seed: int,
    participants: int = 12,
    trials: int = 4,
    effects: Mapping[str, float] | None = None,
    order_effect: float = 0.0,
    conditions: tuple[str, ...] = CONDITIONS,
    slope_sd: Mapping[str, float] | None = None,
) -> pd.DataFrame:
    """Rows of a study: per participant, condition and trial, the person's and the avatar's.

    ``effects`` is each measure's true effect of every condition but the first (added once per
    condition index: condition k gets k times it); ``order_effect`` is added per position after
    the first; ``slope_sd`` is the SD over participants of each measure's effect (a
    participant's own effect drawn around ``effects``; none when not given, and then no draw).
    """
    effects = dict(effects or {})
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(participants):
        order = list(conditions) if i % 2 == 0 else list(reversed(conditions))
        level = {m: rng.normal(0.0, PARTICIPANT_SD[m]) for m in BASE}
        own = {m: effects.get(m, 0.0) + (rng.normal(0.0, slope_sd.get(m, 0.0)) if slope_sd else 0.0)
               for m in BASE}  # fmt: skip
        for position, condition in enumerate(order, start=1):
            k = conditions.index(condition)
            for trial in range(1, trials + 1):
                values = {
                    m: BASE[m] + level[m] + k * own[m] + order_effect * (position - 1)
                    + rng.normal(0.0, TRIAL_SD[m])
                    for m in BASE
                }  # fmt: skip
                design = {
                    "participant": f"p{i:03d}", "block": position, "condition": condition,
                    "trial": trial, "position": position, "partners": "A1",
                    "partner_kind": "avatar", "delay_s": 0.5 * k, "occluded": False,
                    "perturbations": 0, "complete": True,
                }  # fmt: skip
                rows.append(design | values | {"person": "P1", "player_kind": "person"})
                avatar = {m: AVATAR_VALUE for m in BASE} | {"person": "A1", "partners": "P1"}
                rows.append(design | avatar | {"player_kind": "avatar", "partner_kind": "person"})
    return pd.DataFrame(rows)


def dictionary(rows: pd.DataFrame) -> dict[str, dict[str, object]]:
    """A BIDS-style data dictionary of the rows' columns."""
    roles = {"participant": "identifier", "person": "identifier", "trial": "identifier"}
    found: dict[str, dict[str, object]] = {}
    for name in rows.columns:
        entry: dict[str, object] = {"Description": name.replace("_", " ")}
        if name in BASE:
            entry |= {"Role": "measure", "Units": UNITS[name]}
        elif name.startswith("answer_"):
            entry["Role"] = "answer"
        else:
            entry["Role"] = roles.get(name, "design")
        if name == "condition":
            entry["Levels"] = {c: c for c in dict.fromkeys(rows["condition"])}
        found[name] = entry
    return found


def write_study_table(rows: pd.DataFrame, folder: Path, with_dictionary: bool = True) -> Path:
    """Write ``folder/study.csv`` (and ``study.json``) as `study table` does; return the folder."""
    folder.mkdir(parents=True, exist_ok=True)
    rows.to_csv(folder / "study.csv", index=False)
    if with_dictionary:
        (folder / "study.json").write_text(json.dumps(dictionary(rows), indent=2))
    return folder


def scripted_answers(truth: list[str], guesses: list[str], confidence: list[float]) -> pd.DataFrame:
    """Rows of a person's answers, one per trial, with the partner's true kind."""
    n = len(truth)
    return pd.DataFrame({
        "participant": [f"p{i % 3:03d}" for i in range(n)], "person": "P1",
        "player_kind": "person", "condition": "c", "trial": np.arange(n), "position": 1,
        "partner_kind": truth, "guess_kind": guesses,
        "guess_correct": [t == g for t, g in zip(truth, guesses, strict=True)],
        "guess_confidence": confidence, "rms": 0.1,
    })  # fmt: skip


def with_answers(rows: pd.DataFrame, seed: int, right: float = 0.75) -> pd.DataFrame:
    """The rows with a "person or avatar?" answer after each person's trial.

    The partner's true kind alternates with the trial; each guess is right with probability
    ``right``, with a confidence of 0.8 when right and 0.5 when wrong, plus noise.
    """
    rng = np.random.default_rng(seed)
    persons = rows["player_kind"] == "person"
    truth = np.where(rows["trial"] % 2 == 0, "person", "avatar")
    is_right = rng.random(len(rows)) < right
    guess = np.where(is_right, truth, np.where(truth == "person", "avatar", "person"))
    confidence = np.clip(np.where(is_right, 0.8, 0.5) + rng.normal(0, 0.1, len(rows)), 0, 1)
    return rows.assign(
        partner_kind=np.where(persons, truth, rows["partner_kind"]),
        guess_kind=np.where(persons, guess, None),
        guess_correct=np.where(persons, is_right, None),
        guess_confidence=np.where(persons, confidence, np.nan),
        answer_q1=np.where(persons, guess, None),
    )
