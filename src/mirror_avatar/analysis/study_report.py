"""A study's statistics as a paper reports them: analysed, then written as HTML, JSON and CSV.

`analyse_study` runs every statistic on a study table (`mirror_avatar.analysis.statistics`,
`mirror_avatar.analysis.identification`); `write_study_report` writes ``report.html`` (its
verdict first, a plain-language line per comparison, tables, figures of every participant, the
methods paragraph), ``results.json`` (every number, every parameter), ``conditions.csv`` and
``contrasts.csv``.
"""

from __future__ import annotations

import platform
from dataclasses import asdict, dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from mirror_avatar.analysis.identification import Identification, identify
from mirror_avatar.analysis.statistics import (
    BOOTSTRAP_RESAMPLES,
    CONFIDENCE,
    Contrast,
    MeasureModel,
    condition_summaries,
    fit_contrasts,
    participant_means,
)
from mirror_avatar.analysis.study_figures import plot_identification, plot_participants
from mirror_avatar.analysis.study_file import StudyTable
from mirror_avatar.analysis.study_text import (
    comparison_sentence,
    format_p,
    identification_sentence,
    methods_paragraph,
    verdict,
)
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import (
    csv_text,
    json_text,
    write_atomic_files,
)
from mirror_avatar.report import Section, render_report

STUDY_REPORT_FILES = ("report.html", "results.json", "conditions.csv", "contrasts.csv")
"""The files `write_study_report` writes in its folder."""

SOFTWARE = ("mirror-avatar", "numpy", "pandas", "scipy", "statsmodels")


@dataclass(frozen=True)
class StudyAnalysis:
    """Every statistic of a study.

    Parameters
    ----------
    table
        The study table analysed.
    rows
        Its rows analysed: the persons' (participants'), not the avatars'.
    conditions, reference
        The conditions in order, and the one every other is compared with.
    summaries
        `condition_summaries`: mean and bootstrap CI per measure and condition.
    models
        A mixed model per measure that has two conditions to compare.
    identification
        The "person or avatar?" answers scored, None when there are none.
    parameters
        Every parameter, the seed and the software's versions; the table by its file's name
        (``source``), as a report to be shared never holds the researcher's folders.
    notes
        What was left out or could not be computed, in plain words.
    """

    table: StudyTable
    rows: pd.DataFrame
    conditions: list[str]
    reference: str
    summaries: pd.DataFrame
    models: list[MeasureModel]
    identification: Identification | None
    parameters: dict[str, Any]
    notes: list[str]

    @property
    def contrasts(self) -> list[Contrast]:
        """Every model's contrasts, measure by measure."""
        return [c for model in self.models for c in model.contrasts]

    def sentences(self) -> list[str]:
        """Say each comparison in a plain-language line."""
        return [
            comparison_sentence(c, self.table.units(c.measure), len(model.contrasts) > 1)
            for model in self.models
            for c in model.contrasts
        ]

    def verdict(self) -> str:
        """Return the report's first line."""
        return verdict(self.contrasts, self.identification)

    def results(self) -> dict[str, Any]:
        """Every number, for ``results.json``."""
        return {
            "verdict": self.verdict(),
            "sentences": self.sentences(),
            "methods": methods_paragraph(self.parameters),
            "parameters": self.parameters,
            "conditions": self.summaries.to_dict(orient="records"),
            "models": [asdict(model) for model in self.models],
            "identification": None
            if self.identification is None
            else self.identification.to_dict(),
            "notes": self.notes,
        }


def analyse_study(
    table: StudyTable,
    seed: int = 0,
    reference: str | None = None,
    resamples: int = BOOTSTRAP_RESAMPLES,
    confidence: float = CONFIDENCE,
) -> StudyAnalysis:
    """Run every statistic on ``table``.

    Parameters
    ----------
    table
        The study table.
    seed
        Seed of the bootstrap's generator.
    reference
        The condition the others are compared with; default the first (the dictionary's first
        level of ``condition``, else the first in the table).
    resamples, confidence
        Bootstrap resamples and the confidence level of every interval.

    Raises
    ------
    InputError
        ``reference`` is not a condition of the table.
    """
    conditions = table.conditions()
    if reference is None:
        reference = conditions[0]
    elif reference not in conditions:
        raise InputError("--reference", f"no condition {reference!r} in {table.source}; its "
                         f"conditions are {', '.join(conditions)}")  # fmt: skip
    rows, notes = _participants_rows(table.rows)
    rows, incomplete = _complete_rows(rows, table.source)
    notes += _incomplete_note(incomplete)
    rows, left_out = _finite(rows, table.outcomes)
    notes += left_out
    if table.skipped_measures:
        notes.append(f"not numbers, so not averaged: {', '.join(table.skipped_measures)}")
    summaries = condition_summaries(rows, table.outcomes, conditions, seed, resamples, confidence)
    models, untested = [], []
    for measure in table.outcomes:
        model = fit_contrasts(rows, measure, conditions, reference, confidence)
        if model is None:
            untested.append(measure)
        else:
            models.append(model)
            notes += [f"{measure}: {note}" for note in model.notes]
    if untested:
        notes.append(
            f"no comparison (fewer than two conditions or participants): {', '.join(untested)}"
        )
    parameters = {
        "source": table.source.name, "participants": int(rows["participant"].nunique()),
        "rows": len(rows), "incomplete_rows": incomplete, "conditions": conditions,
        "reference": reference,
        "measures": table.measures, "rated_answers": table.rated_answers, "seed": seed,
        "bootstrap_resamples": resamples,
        "bootstrap_method": "BCa", "confidence": confidence,
        "model": "measure ~ C(condition, reference) + position, random intercept per "
                 "participant, REML, Wald z tests, Holm over a measure's contrasts",
        "identification": "exact binomial against 0.5; d' and c with log-linear correction "
                          "when a rate is 0 or 1; Mann-Whitney U for confidence",
        "versions": _versions(),
    }  # fmt: skip
    return StudyAnalysis(
        table=table, rows=rows, conditions=conditions, reference=reference, summaries=summaries,
        models=models, identification=identify(rows, confidence), parameters=parameters,
        notes=notes,
    )  # fmt: skip


def write_study_report(analysis: StudyAnalysis, out_dir: str | Path) -> Path:
    """Write `STUDY_REPORT_FILES` in ``out_dir`` (created if missing); return the HTML's path.

    All four or none (`mirror_avatar.files.atomic.write_atomic_files`): a failure leaves each file
    as it was.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    html, results, conditions, contrasts = STUDY_REPORT_FILES
    metadata = {
        "table": analysis.parameters["source"],
        "participants": analysis.parameters["participants"],
        "seed": analysis.parameters["seed"],
        "mirror-avatar": analysis.parameters["versions"]["mirror-avatar"],
    }
    page = render_report(_sections(analysis), "mirror-avatar: study report", metadata,
                         lead=analysis.verdict())  # fmt: skip
    contents = {
        html: page,
        results: json_text(analysis.results()),
        conditions: csv_text(analysis.summaries, index=False),
        contrasts: csv_text(_contrast_table(analysis), index=False),
    }
    write_atomic_files(out, contents)
    return out / html


def _participants_rows(rows: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Keep the persons' rows (the participants'); avatars are not participants."""
    if "player_kind" not in rows:
        return rows, []
    persons = rows[rows["player_kind"] == "person"]
    left = len(rows) - len(persons)
    return persons, [
        f"{left} rows of avatars left out: only persons are participants"
    ] if left else []


def _complete_rows(rows: pd.DataFrame, source: Path) -> tuple[pd.DataFrame, int | None]:
    """Leave out the rows of trials that stopped before their end; return how many.

    **Choice**: a trial whose ``complete`` is false (aborted, ended by a drop or a crash) is
    left out, its measures being of part of a trial or none. None: the table has no
    ``complete`` column (every row kept, as nothing says which trials ran to their end).

    Raises
    ------
    InputError
        Every row is of an incomplete trial.
    """
    if "complete" not in rows:
        return rows, None
    complete = rows["complete"].eq(True)
    if len(rows) and not complete.any():
        raise InputError(source, "every trial stopped before its end (complete false): no trial "
                         "to analyse")  # fmt: skip
    return rows[complete], int((~complete).sum())


def _incomplete_note(incomplete: int | None) -> list[str]:
    """Say what `_complete_rows` left out, or that the table cannot tell."""
    if incomplete is None:
        return ["the table has no complete column: every trial kept, complete or not"]
    if not incomplete:
        return []
    return [f"{incomplete} rows of incomplete trials left out (complete false: stopped before "
            "their end)"]  # fmt: skip


def _finite(rows: pd.DataFrame, outcomes: list[str]) -> tuple[pd.DataFrame, list[str]]:
    """Make the outcomes' infinite values missing, so no statistic uses them; say how many."""
    infinite = {
        name: np.isinf(rows[name].to_numpy(np.float64, na_value=np.nan)) for name in outcomes
    }
    notes = [
        f"{name}: {found.sum()} of {found.size} values left out, not finite (infinite)"
        for name, found in infinite.items()
        if found.any()
    ]
    if not notes:
        return rows, []
    return rows.assign(**{name: rows[name].mask(found) for name, found in infinite.items()}), notes


def _contrast_table(analysis: StudyAnalysis) -> pd.DataFrame:
    columns = ["measure", "condition", "reference", "participants", "reference_mean",
               "condition_mean", "difference", "ci_low", "ci_high", "p", "p_holm",
               "standardised", "d_z", "t", "t_p", "wilcoxon_p"]  # fmt: skip
    return pd.DataFrame([asdict(c) for c in analysis.contrasts], columns=columns)


def _contrast_displays(analysis: StudyAnalysis) -> dict[str, pd.DataFrame]:
    """Show the contrasts in two narrow tables: the model's, and the participants' means'."""
    table = _contrast_table(analysis)
    index = pd.MultiIndex.from_frame(table[["measure", "condition"]])
    interval = [f"{low:.4g} to {high:.4g}" for low, high in zip(table["ci_low"], table["ci_high"],
                                                               strict=True)]  # fmt: skip
    model = {
        "difference": table["difference"], "95 % CI": interval,
        "p": table["p"].map(_p_cell), "p Holm": table["p_holm"].map(_p_cell),
        "standardised": table["standardised"],
    }  # fmt: skip
    paired = {
        "n": table["participants"], analysis.reference: table["reference_mean"],
        "condition": table["condition_mean"], "d_z": table["d_z"],
        "t-test p": table["t_p"].map(_p_cell), "Wilcoxon p": table["wilcoxon_p"].map(_p_cell),
    }  # fmt: skip
    return {
        f"Mixed model: each condition's difference from {analysis.reference!r} (measure units), "
        "its 95 % CI, p (Holm-corrected over a measure's contrasts) and the difference over "
        "the model's SD": pd.DataFrame(model).set_index(index),
        "Participants' means: the reference's and the condition's, Cohen's d_z, paired t-test "
        "and Wilcoxon signed-rank test": pd.DataFrame(paired).set_index(index),
    }


def _p_cell(p: float) -> str:
    return format_p(p).removeprefix("p = ").removeprefix("p ")


def _model_table(analysis: StudyAnalysis) -> pd.DataFrame:
    return pd.DataFrame([{
        "measure": m.measure, "trials": m.rows, "participants": m.participants,
        "order slope per position": m.position_slope, "order p": m.position_p,
        "participant variance": m.participant_variance, "residual variance": m.residual_variance,
    } for m in analysis.models]).set_index("measure")  # fmt: skip


def _sections(analysis: StudyAnalysis) -> list[Section]:
    table = analysis.table
    summaries = analysis.summaries.set_index(["measure", "condition"])
    figures = {
        f"{measure}: each participant's mean per condition (grey lines), the mean over "
        f"participants with its {analysis.parameters['confidence']:.0%} bootstrap CI": (
            plot_participants(
                participant_means(analysis.rows, measure, analysis.conditions),
                analysis.summaries[analysis.summaries["measure"] == measure],
                f"{measure} ({table.units(measure)})" if table.units(measure) else measure,
            )
        )
        for measure in table.outcomes
    }
    sections = [
        Section("comparisons", "In words", text=analysis.sentences() + analysis.notes),
        Section("conditions", "Each condition: mean over participants and its CI",
                tables={"Mean, bootstrap CI and SD of the participants' means": summaries},
                figures=figures),
        Section("contrasts", "Contrasts within participants (mixed models)", tables={
            **_contrast_displays(analysis),
            "Order (position in the participant's order) and variances": _model_table(analysis),
        } if analysis.models else {}),
    ]  # fmt: skip
    if analysis.identification is not None:
        sections.append(_identification_section(analysis.rows, analysis.identification))
    sections.append(Section("methods", "Methods", text=[methods_paragraph(analysis.parameters)]))
    return sections


def _identification_section(rows: pd.DataFrame, found: Identification) -> Section:
    pooled = pd.DataFrame([asdict(found.detection)], index=["all answers"]).T
    return Section(
        "identification", "Identification: person or avatar?",
        text=[identification_sentence(found)],
        tables={"Signal detection over all answers (\"person\" the signal)": pooled,
                "Per condition (said_person: the share of answers \"person\")":
                    found.per_condition,
                "Per person who answered": found.per_person},
        figures={"Answers \"person\" by the partner's true kind (each person a line), and "
                 "confidence of right and wrong answers": plot_identification(rows, found)},
    )  # fmt: skip


def _versions() -> dict[str, str]:
    found = {"python": platform.python_version()}
    for name in SOFTWARE:
        try:
            found[name] = version(name)
        except PackageNotFoundError:
            found[name] = "not installed"
    return found
