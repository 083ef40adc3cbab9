"""The two ways of moving between a patient's and a target's motion, measured (METHODS section 10).

For K stages of weight w_k = (k - 1) / (K - 1) and each method of
`mirror_avatar.training.curriculum`, a stage's motion is drawn (``n_draws`` draws of `DURATION` s)
and compared with the people's own trials: the EMD of its velocity IMS to the patient's and to the
target's pooled trials, and its velocity strokes' skewness and kurtosis (mean, and the share within
the human ranges). Then a virtual trainer moving like the patient follows a virtual trainer leading
with the stage's motion (``n_sessions`` seeded sessions), and their coordination is measured (CV and
RMS): a stage the patient cannot coordinate with is no use however its IMS looks.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from mirror_avatar.common.progress import counted
from mirror_avatar.common.seeds import draw_seeds
from mirror_avatar.dynamics import preset
from mirror_avatar.engine.batch import play_compiled
from mirror_avatar.engine.loop import count_samples
from mirror_avatar.experiments.cyber_player import measure
from mirror_avatar.figures.signatures import HUMAN_KURTOSIS, HUMAN_SKEWNESS
from mirror_avatar.files.trials import DEFAULT_RATE, Trial
from mirror_avatar.metrics import TRIM
from mirror_avatar.motion.generator import PAPER_SYMBOLS, IMSGenerator
from mirror_avatar.players import VirtualTrainer
from mirror_avatar.report import Section
from mirror_avatar.signatures.signature import compute_emd, compute_ims, stroke_moments
from mirror_avatar.training.curriculum import BLOCK_SECONDS, METHODS, StageMotion

DURATION = 60.0
N_DRAWS, QUICK_DRAWS = 6, 2
N_SESSIONS, QUICK_SESSIONS = 6, 2
STAGES, QUICK_STAGES = 5, 3
TITLE = "Rehabilitation curriculum: moving from a patient's motion to a target's"


def run(trials: Sequence[Trial], quick: bool = False, seed: int = 0) -> Section:
    """Measure both methods with the first style (group) as the patient, the second as target.

    Parameters
    ----------
    trials
        Solo trials grouped by person or style (at least two groups of two trials; otherwise
        the section says it was skipped).
    quick
        `QUICK_STAGES` stages, `QUICK_DRAWS` draws and `QUICK_SESSIONS` sessions, and the
        people's generators with the paper's fixed codebook (`PAPER_SYMBOLS`) instead of one
        chosen by cross-validation (most of the section's time).
    seed
        Seeds the generators, the drawn motion and the sessions.
    """
    groups: dict[str, list[Trial]] = {}
    for trial in trials:
        groups.setdefault(trial.group, []).append(trial)
    people = [name for name, members in groups.items() if len(members) >= 2][:2]
    if len(people) < 2:
        return Section("curriculum", TITLE, ["Skipped: it needs two groups of two trials."])
    patient, target = (groups[name] for name in people)
    sizes = (QUICK_STAGES, QUICK_DRAWS, QUICK_SESSIONS) if quick else (STAGES, N_DRAWS, N_SESSIONS)
    symbols = PAPER_SYMBOLS if quick else "auto"
    fitted = [
        IMSGenerator(symbols, rate=DEFAULT_RATE, random_state=seed).fit(t)
        for t in (patient, target)
    ]
    by_role: dict[str, Sequence[Trial]] = {"patient": patient, "target": target}
    table = measure_stages(fitted[0], fitted[1], by_role, *sizes, seed=seed)
    own = {"patient": own_emd(patient), "target": own_emd(target)}
    section = curriculum_section(table, own, people[0], people[1])
    section.text.append(
        f"The people's generators have the paper's {PAPER_SYMBOLS} symbols (a quick run)."
        if quick
        else "The people's generators have the codebook size chosen by cross-validation."
    )
    return section


def curriculum_section(
    table: pd.DataFrame, own: dict[str, float], patient: str, target: str
) -> Section:
    """Describe a `measure_stages` table, and the people's own trial-to-trial EMD, as a section."""
    text = [
        f"Patient: {patient}; target: {target}. Stage k moves with weight w = (k - 1) / "
        "(K - 1) between them: stage 1 as the patient, stage K as the target. Mixture: the "
        f"velocity in blocks of {BLOCK_SECONDS:g} s, each from the target's generator with "
        "probability w, else from the patient's. Displacement interpolation: the patient's "
        "velocity moved by w along the map between the two quantile functions. Columns: EMD "
        "of the stage's velocity IMS to each person's pooled trials; the velocity strokes' "
        "skewness, kurtosis and share within the human ranges; the CV and RMS of a follower "
        "moving like the patient with a leader moving as the stage.",
        f"Trial-to-trial EMD of the patient {own['patient']:.4f}, of the target "
        f"{own['target']:.4f}: the first stage should lie within the first, the last within "
        "the second.",
    ]
    return Section(
        key="curriculum",
        title=TITLE,
        text=text,
        tables={"Stages of each method": table.round(4)},
        metrics={"own_emd": own, "stages": table.reset_index().to_dict(orient="records")},
    )


def measure_stages(
    patient: IMSGenerator,
    target: IMSGenerator,
    trials: Mapping[str, Sequence[Trial]],
    stages: int = STAGES,
    n_draws: int = N_DRAWS,
    n_sessions: int = N_SESSIONS,
    seed: int = 0,
) -> pd.DataFrame:
    """One row per method and stage: weight, EMD to patient and target, strokes, coordination.

    Parameters
    ----------
    patient, target
        The two people's generators.
    trials
        ``"patient"`` and ``"target"`` -> their trials, which the stages' IMS are compared with.
    stages
        K, at least 2: stage 1 is the patient's motion (w = 0), stage K the target's (w = 1).
    n_draws, n_sessions
        Draws of `DURATION` s of each stage's motion; sessions with the patient-like follower.
    seed
        Seeds the drawn motion and the sessions.
    """
    people = {name: _pooled_ims(trials[name]) for name in ("patient", "target")}
    rows = []
    plan = [(method, k) for method in METHODS for k in range(1, stages + 1)]
    for method, k in counted(plan, len(plan), "curriculum stages", "stage"):
        weight = (k - 1) / (stages - 1)
        motion = StageMotion(patient, target, weight, method)
        rows.append(
            {"method": method, "stage": k, "weight": round(weight, 4)}
            | _motion_row(motion, people, n_draws, seed)
            | _coordination(patient, motion, n_sessions, seed)
        )
    return pd.DataFrame(rows).set_index(["method", "stage"])


def own_emd(trials: Sequence[Trial]) -> float:
    """Mean EMD between the IMS of two of a person's trials (their trial-to-trial variation)."""
    ims = [compute_ims(t.resampled(DEFAULT_RATE).velocity()) for t in trials]
    return float(np.mean([compute_emd(a, b) for k, a in enumerate(ims) for b in ims[k + 1 :]]))


def _pooled_ims(trials: Sequence[Trial]) -> np.ndarray:
    return compute_ims(np.concatenate([t.resampled(DEFAULT_RATE).velocity() for t in trials]))


def _motion_row(
    motion: StageMotion, people: dict[str, np.ndarray], n_draws: int, seed: int
) -> dict[str, Any]:
    """EMD of the stage's IMS to each person's, and its strokes."""
    n_samples = int(round(DURATION * motion.rate))
    draws = [motion.sample_velocity(n_samples, s) for s in draw_seeds([seed, 7], n_draws)]
    ims = compute_ims(np.concatenate(draws))
    moments = np.concatenate([stroke_moments(v) for v in draws]).reshape(-1, 2)
    human = (
        (moments[:, 0] > HUMAN_SKEWNESS[0])
        & (moments[:, 0] < HUMAN_SKEWNESS[1])
        & (moments[:, 1] > HUMAN_KURTOSIS[0])
        & (moments[:, 1] < HUMAN_KURTOSIS[1])
    )
    return {
        "EMD to patient": compute_emd(ims, people["patient"]),
        "EMD to target": compute_emd(ims, people["target"]),
        "stroke skewness": float(moments[:, 0].mean()),
        "stroke kurtosis": float(moments[:, 1].mean()),
        "strokes in human range": float(human.mean()),
    }


def _coordination(
    patient: IMSGenerator, motion: StageMotion, n_sessions: int, seed: int
) -> dict[str, float]:
    """CV and RMS of a patient-like follower with a leader moving as the stage."""
    leader = VirtualTrainer(preset("leader"), motion, label="stage")
    follower = VirtualTrainer(preset("follower"), patient, label="patient")
    n_samples = count_samples(DURATION, leader.period)
    results = [
        measure(play_compiled([leader, follower], n_samples, s).trimmed(TRIM))
        for s in draw_seeds([seed, 8], n_sessions)
    ]
    return {
        "CV with the patient": float(np.nanmean([r["cv"] for r in results])),
        "RMS with the patient": float(np.mean([r["rms"] for r in results])),
    }
