"""Validation of the virtual trainer (paper section VI-B; METHODS sections 5 and 6).

A virtual trainer (VT) whose IMS generator is fitted on one movement style (the reference style,
"slow" when the data have it, else the first group: a **choice**, the paper used one person's
recordings) plays two conditions:

- *VT follows*: every recorded solo trial, of every style, is replayed open-loop as the leader
  (`mirror_avatar.players.RecordedPlayer`) and the VT with the follower preset follows it;
- *VT leads*: the VT with the leader preset leads another VT (follower preset) whose generator is
  fitted on the other style; as a control, it also leads a VT follower of its own style.

Each condition reports the paper's numbers: CV (the paper's "circular variance", the mean resultant
length of the relative phase), RMSE, relative phase mean and SD, EMD of the VT's velocity IMS to
its partner's, to its own reference velocities, and to each style's signature.

Sign convention: relative phase = partner minus VT (player 0 is always the partner, player 1 the
VT under test), positive when the partner is ahead. The paper's numbers read the same way
(positive +0.394 when the VT follows a person, negative -0.664 when it leads).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.dynamics import FOLLOWER, LEADER
from mirror_avatar.engine.loop import play
from mirror_avatar.figures.sessions import plot_positions, plot_relative_phase
from mirror_avatar.figures.signatures import plot_ims
from mirror_avatar.files.trials import DEFAULT_RATE, Trial
from mirror_avatar.metrics import TRIM, compute_relative_phase, session_metrics
from mirror_avatar.motion.generator import PAPER_EMISSION, PAPER_SYMBOLS, IMSGenerator
from mirror_avatar.players import RecordedPlayer, VirtualTrainer
from mirror_avatar.report import Section
from mirror_avatar.sessions.session import Session
from mirror_avatar.signatures.signature import DEFAULT_BINS, compute_emd, compute_ims

REFERENCE_STYLE = "slow"
"""Style the VT under test learns its signature from when the data have it (**choice**)."""

PARTNER_STYLE = "fast"
"""Style of the VT follower it leads when the data have it (**choice**)."""


LEAD_SESSIONS = 20
"""Sessions of the VT leading (5 in quick mode)."""

LEAD_DURATION = 60.0
"""Length (s) of a session of the VT leading, as the recorded trials."""

PAPER = {
    "follows": {"phase_locking": 0.933, "rmse": 0.112, "mean_relative_phase": 0.394},
    "leads": {"phase_locking": 0.868, "rmse": 0.122, "mean_relative_phase": -0.664},
}
"""The paper's numbers (section VI-B): VT following a person, VT leading."""

EXAMPLE_SECONDS = 20.0
"""Length of the example time series shown."""


@dataclass
class Condition:
    """The sessions of one condition and their metrics (player 0 partner, player 1 the VT).

    ``name`` labels its rows; ``paper`` is its key in `PAPER`.
    """

    name: str
    paper: str
    sessions: list[Session]
    partner_styles: list[str]
    metrics: list[dict[str, float | None]]


def run(
    trials: Sequence[Trial],
    quick: bool = False,
    seed: int = 0,
    reference_style: str | None = None,
    partner_style: str | None = None,
) -> Section:
    """Validate the virtual trainer against recorded people and against another VT.

    Parameters
    ----------
    trials
        Solo trials of at least two groups (styles or people; any rate, resampled to 100 Hz).
    quick
        Play `LEAD_SESSIONS` // 4 leading sessions per partner instead of `LEAD_SESSIONS`.
    seed
        Seeds the generators' k-means and every session (spawned with `numpy.random.SeedSequence`).
    reference_style, partner_style
        The VT's own group and its VT follower's; by default `choose_styles`.

    Returns
    -------
    Section
        Summary and per-session tables next to the paper's numbers, figures (example time series,
        relative-phase distributions, velocity distributions) and metrics.

    Raises
    ------
    InputError
        When a style has no trials, or the trials form only one group.
    """
    reference_style, partner_style = choose_styles(trials, reference_style, partner_style)
    by_style = _split_styles(trials, (reference_style, partner_style))
    generators = {
        style: IMSGenerator(
            PAPER_SYMBOLS, rate=DEFAULT_RATE, random_state=seed, emission=PAPER_EMISSION
        ).fit(group)
        for style, group in by_style.items()
    }
    n_lead = LEAD_SESSIONS // 4 if quick else LEAD_SESSIONS
    follow_trials = [t for group in by_style.values() for t in group]
    seeds = [int(s) for s in spawn_seeds(seed, len(follow_trials) + 2 * n_lead)]
    follows = play_follow_sessions(follow_trials, generators[reference_style], seeds)
    lead_seeds = seeds[len(follow_trials) :]
    own = generators[reference_style]
    leads = [
        play_lead_sessions(own, generators[partner_style], lead_seeds[:n_lead], "leads"),
        play_lead_sessions(own, own, lead_seeds[n_lead:], "leads (same-style VT)"),
    ]
    signatures = {
        style: compute_ims(np.concatenate([t.velocity() for t in group]))
        for style, group in by_style.items()
    }
    summary = summarise([follows, *leads], signatures, reference_style)
    metrics = _metrics(summary, follows, leads, seeds, seed, reference_style, partner_style)
    return Section(
        key="virtual_trainer",
        title="Virtual trainer: following people and leading",
        text=_describe(summary, reference_style, partner_style, len(follow_trials), n_lead),
        tables={
            "Virtual trainer against the paper (player 1 = partner, player 2 = VT; relative "
            "phase = partner minus VT, positive = partner ahead)": summary,
            "Each recorded person as leader, the VT following": _session_table(follows),
        },
        figures=_figures(follows, leads, by_style, reference_style),
        metrics=metrics,
    )


def choose_styles(
    trials: Sequence[Trial], reference: str | None = None, partner: str | None = None
) -> tuple[str, str]:
    """Resolve the reference and partner groups left as None (**choice**).

    `REFERENCE_STYLE` and `PARTNER_STYLE` when the trials have those groups (the bundled data),
    otherwise the first two groups in order of appearance (for example two people).

    Raises
    ------
    InputError
        When the trials form fewer than two groups.
    """
    groups = list(dict.fromkeys(str(t.group) for t in trials))
    if reference is None and partner is None and {REFERENCE_STYLE, PARTNER_STYLE} <= set(groups):
        return REFERENCE_STYLE, PARTNER_STYLE
    others = [g for g in groups if g not in (reference, partner)]
    if len(others) < (reference is None) + (partner is None):
        raise InputError(
            "trials",
            f"the virtual-trainer validation needs two groups of trials, found {groups}; "
            "give trials of two people or styles (--group-by)",
        )
    if reference is None:
        reference = others.pop(0)
    if partner is None:
        partner = others.pop(0)
    return reference, partner


def _split_styles(trials: Sequence[Trial], styles: tuple[str, str]) -> dict[str, list[Trial]]:
    by_style = {
        style: [t.resampled(DEFAULT_RATE) for t in trials if t.group == style] for style in styles
    }
    empty = [style for style, group in by_style.items() if not group]
    if empty or styles[0] == styles[1]:
        raise InputError(
            "trials", f"the virtual-trainer validation needs trials of two styles {styles}"
        )
    return by_style


def play_follow_sessions(
    trials: Sequence[Trial], generator: IMSGenerator, seeds: Sequence[int]
) -> Condition:
    """Play each recorded trial as leader (player 0) against a follower VT (player 1).

    Each session lasts as long as its recording; session i uses ``seeds[i]``.
    """
    sessions = []
    for trial, seed in zip(trials, seeds, strict=False):
        vt = VirtualTrainer(FOLLOWER, generator, label="VT follower")
        duration = float(trial.times[-1] - trial.times[0])
        sessions.append(play([RecordedPlayer(trial), vt], duration, seed, ("leader", "follower")))
    styles = [str(t.group) for t in trials]
    metrics = [session_metrics(s, TRIM) for s in sessions]
    return Condition("follows", "follows", sessions, styles, metrics)


def play_lead_sessions(
    generator: IMSGenerator, partner_generator: IMSGenerator, seeds: Sequence[int], name: str
) -> Condition:
    """Play the leader VT (player 1) with a follower VT (player 0) of ``partner_generator``.

    One `LEAD_DURATION` session per seed; ``name`` labels the condition.
    """
    sessions = []
    for seed in seeds:
        partner = VirtualTrainer(FOLLOWER, partner_generator, label="VT follower (partner)")
        vt = VirtualTrainer(LEADER, generator, label="VT leader")
        sessions.append(play([partner, vt], LEAD_DURATION, seed, ("follower", "leader")))
    styles = ["VT"] * len(sessions)
    metrics = [session_metrics(s, TRIM) for s in sessions]
    return Condition(name, "leads", sessions, styles, metrics)


def compute_style_emds(
    condition: Condition, signatures: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """EMD between the VT's velocity IMS in each session and each style's signature."""
    vt_ims = [compute_ims(s.trimmed(TRIM).velocities[1]) for s in condition.sessions]
    return {
        style: np.array([compute_emd(ims, signature) for ims in vt_ims])
        for style, signature in signatures.items()
    }


def summarise(
    conditions: Sequence[Condition],
    signatures: dict[str, np.ndarray],
    reference_style: str,
) -> pd.DataFrame:
    """One row per condition (and per partner style when following): means and SDs over sessions.

    Columns: ``sessions``, ``cv``/``cv_sd``, ``rmse``/``rmse_sd`` (units), ``phase`` (mean of
    the sessions' circular mean relative phase, rad), ``phase_sd`` (mean within-session circular
    SD, rad), ``lag`` (s), the EMDs of the VT to its partner, to its own reference velocities and
    to each style, and the paper's CV, RMSE and phase.
    """
    rows = {}
    for condition in conditions:
        emds = compute_style_emds(condition, signatures)
        groups = sorted(set(condition.partner_styles))
        for group in [*groups, None] if len(groups) > 1 else [None]:
            name = condition.name if group is None else f"{condition.name} ({group} people)"
            mask = np.array([group is None or g == group for g in condition.partner_styles])
            rows[name] = _row(condition, mask, emds, reference_style)
    return pd.DataFrame.from_dict(rows, orient="index")


def _row(
    condition: Condition, mask: np.ndarray, emds: dict[str, np.ndarray], reference_style: str
) -> dict[str, Any]:
    selected = [m for m, keep in zip(condition.metrics, mask, strict=True) if keep]

    def values(key: str) -> np.ndarray:
        return np.array([float(v) for m in selected if (v := m[key]) is not None])

    paper = PAPER[condition.paper]
    row: dict[str, Any] = {
        "sessions": len(selected),
        "cv": values("phase_locking").mean(),
        "cv_sd": values("phase_locking").std(ddof=1) if len(selected) > 1 else np.nan,
        "rmse": values("rmse").mean(),
        "rmse_sd": values("rmse").std(ddof=1) if len(selected) > 1 else np.nan,
        "phase": values("mean_relative_phase").mean(),
        "phase_sd": values("sd_relative_phase").mean(),
        "lag": values("time_lag").mean(),
        "emd_partner": values("emd_players").mean(),
        "emd_own_reference": values("emd_reference_1").mean(),
    }
    for style, emd in emds.items():
        label = "reference" if style == reference_style else "other"
        row[f"emd_{label}_style ({style})"] = emd[mask].mean()
    row |= {
        f"paper_{key}": value
        for key, value in zip(("cv", "rmse", "phase"), paper.values(), strict=True)
    }
    return row


def _session_table(condition: Condition) -> pd.DataFrame:
    rows = []
    for session, style, m in zip(
        condition.sessions, condition.partner_styles, condition.metrics, strict=True
    ):
        rows.append(
            {
                "leader": session.labels[0],
                "style": style,
                "cv": m["phase_locking"],
                "rmse": m["rmse"],
                "phase": m["mean_relative_phase"],
                "lag": m["time_lag"],
                "emd_partner": m["emd_players"],
            }
        )
    return pd.DataFrame(rows).set_index("leader")


def _figures(
    follows: Condition,
    leads: Sequence[Condition],
    by_style: dict[str, list[Trial]],
    reference_style: str,
) -> dict[str, Any]:
    example = next(i for i, style in enumerate(follows.partner_styles) if style == reference_style)
    follow_session, lead_session = follows.sessions[example], leads[0].sessions[0]
    n = int(round(EXAMPLE_SECONDS / follow_session.period)) + 1
    phases = {
        f"VT follows ({style} people)": _phases(follows, style)
        for style in sorted(set(follows.partner_styles))
    }
    phases |= {f"VT {condition.name}": _phases(condition, None) for condition in leads}
    velocities = {
        f"{style} people": compute_ims(np.concatenate([t.velocity() for t in group]))
        for style, group in by_style.items()
    }
    for condition in (follows, *leads):
        pooled = np.concatenate([s.velocities[1] for s in condition.sessions])
        velocities[f"VT ({condition.name})"] = compute_ims(pooled)
    return {
        f"A recorded {reference_style} person leading, the VT following (first "
        f"{EXAMPLE_SECONDS:g} s)": plot_positions(
            follow_session.times[:n],
            {
                f"person {follow_session.labels[0]}": follow_session.positions[0][:n],
                "VT follower": follow_session.positions[1][:n],
            },
            title="VT follows a person",
        ),
        f"The VT leading a VT follower (first {EXAMPLE_SECONDS:g} s)": plot_positions(
            lead_session.times[:n],
            {
                "VT follower (partner)": lead_session.positions[0][:n],
                "VT leader": lead_session.positions[1][:n],
            },
            title="VT leads a VT",
        ),
        "Relative phase, partner minus VT (dashed: circular mean)": plot_relative_phase(
            phases, title="Relative phase (positive: partner ahead)"
        ),
        "Velocity distributions of the people and of the VT (paper figure 7)": plot_ims(
            velocities, DEFAULT_BINS, title="Velocity distributions"
        ),
    }


def _phases(condition: Condition, style: str | None) -> np.ndarray:
    chunks = []
    for session, group in zip(condition.sessions, condition.partner_styles, strict=True):
        if style is None or group == style:
            x = session.trimmed(TRIM).positions
            chunks.append(compute_relative_phase(x[0], x[1]))
    return np.concatenate(chunks)


def _metrics(
    summary: pd.DataFrame,
    follows: Condition,
    leads: Sequence[Condition],
    seeds: list[int],
    seed: int,
    reference_style: str,
    partner_style: str,
) -> dict[str, Any]:
    return {
        "seed": seed,
        "session_seeds": seeds,
        "reference_style": reference_style,
        "partner_style": partner_style,
        "trim": TRIM,
        "convention": "relative phase and lag: partner (player 0) minus VT (player 1)",
        "summary": summary.to_dict(orient="index"),
        "follows": [
            dict(m, leader=s.labels[0])
            for m, s in zip(follows.metrics, follows.sessions, strict=True)
        ],
        "leads": leads[0].metrics,
        "leads_same_style": leads[1].metrics,
        "paper": PAPER,
    }


def _describe(
    summary: pd.DataFrame, reference_style: str, partner_style: str, n_follow: int, n_lead: int
) -> list[str]:
    own = summary.loc[f"follows ({reference_style} people)"]
    leads, same = summary.loc["leads"], summary.loc["leads (same-style VT)"]
    return [
        f"The VT under test has a signature learned from the {reference_style} trials. It follows "
        f"each of the {n_follow} recorded trials replayed as leader, and leads a VT follower with "
        f"the {partner_style} signature (and, as a control, one with its own signature) in "
        f"{n_lead} sessions of {LEAD_DURATION:g} s each. The first {TRIM:g} s of each session are "
        'left out. CV is the paper\'s "circular variance", the mean resultant length of the '
        "relative phase (1 = phase locked).",
        f"Following {reference_style} people: CV {own['cv']:.3f}, RMSE {own['rmse']:.3f}, "
        f"relative phase {own['phase']:+.3f} rad (paper, with a person: CV 0.933, RMSE 0.112, "
        f"+0.394). Leading the {partner_style} VT: CV {leads['cv']:.3f}, RMSE "
        f"{leads['rmse']:.3f}, relative phase {leads['phase']:+.3f} rad (paper, leading a person: "
        f"0.868, 0.122, -0.664); leading a VT of its own style: CV {same['cv']:.3f}, RMSE "
        f"{same['rmse']:.3f}, relative phase {same['phase']:+.3f} rad. Positive phase: the "
        "partner is ahead, so the VT lags when it follows and is ahead when it leads if the "
        "signs match. A VT follower keeps a weak pull (theta_s = 0.1) to its own reference "
        "velocity, so a follower with another style locks less tightly to the leader than a "
        "person following would.",
    ]
