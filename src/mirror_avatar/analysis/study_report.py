"""A study's statistics as a paper reports them: analysed, then written as HTML, JSON and CSV.

`analyse_study` runs every statistic on a study table (`mirror_avatar.analysis.statistics`,
`mirror_avatar.analysis.identification`), the protocol's declared hypothesis first when one is
given (`mirror_avatar.analysis.hypothesis`: the confirmatory test, every other comparison
exploratory with Benjamini-Hochberg q-values); `write_study_report` writes ``report.html`` (its
verdict first, the confirmatory test, a plain-language line per exploratory comparison, tables,
figures of every participant, the methods paragraph), ``results.json`` (every number, every
parameter), ``conditions.csv`` and ``contrasts.csv``.
"""

from __future__ import annotations

import platform
from dataclasses import asdict, dataclass, replace
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from mirror_avatar.analysis.circular import (
    circular_contrasts,
    circular_mean,
    circular_summaries,
)
from mirror_avatar.analysis.dictionary import is_angle
from mirror_avatar.analysis.hypothesis import (
    CONFIRMATORY_MODEL,
    EXPLORATORY_MODEL,
    ConfirmatoryTest,
    confirm,
    confirmatory_model,
)
from mirror_avatar.analysis.identification import Identification, identify
from mirror_avatar.analysis.multiple_tests import benjamini_hochberg
from mirror_avatar.analysis.plan import RegisteredPlan, plan_deviations
from mirror_avatar.analysis.statistics import (
    BOOTSTRAP_RESAMPLES,
    CONFIDENCE,
    MIXED_MODEL,
    Contrast,
    FactorTest,
    MeasureModel,
    condition_summaries,
    fit_contrasts,
    participant_means,
)
from mirror_avatar.analysis.study_figures import plot_identification, plot_participants
from mirror_avatar.analysis.study_file import StudyTable
from mirror_avatar.analysis.study_text import (
    NO_UNITS,
    comparison_sentence,
    confirmatory_sentence,
    factor_sentence,
    format_p,
    identification_sentence,
    methods_paragraph,
    number,
    verdict,
)
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import (
    csv_text,
    json_text,
    write_atomic_files,
)
from mirror_avatar.lab.design.protocol import Analysis, Protocol
from mirror_avatar.report import Section, render_report

STUDY_REPORT_FILES = ("report.html", "results.json", "conditions.csv", "contrasts.csv")
"""The files `write_study_report` writes in its folder."""

SOFTWARE = ("mirror-avatar", "numpy", "pandas", "scipy", "statsmodels")

FEW_PARTICIPANTS = 6
"""Fewer participants than this get a warning in the report's notes (**choice**: the smallest
number at which the two-sided Wilcoxon signed-rank cross-check can reach p < 0.05, as its
smallest p is 2 / 2^n, 0.0625 with 5; below it, only the normal-theory tests can, on too few
participants to check their normality)."""


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
    confirmatory
        The declared hypothesis's test per primary measure, None when none was declared.
    deviations
        Each way the analysis run differs from the registered plan
        (`mirror_avatar.analysis.plan.plan_deviations`), None when no plan was given.
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
    confirmatory: list[ConfirmatoryTest] | None = None
    deviations: list[str] | None = None

    @property
    def contrasts(self) -> list[Contrast]:
        """Every model's contrasts, measure by measure."""
        return [c for model in self.models for c in model.contrasts]

    @property
    def factors(self) -> list[FactorTest]:
        """Every model's tests of the partner's kind and condition x kind, measure by measure."""
        return [f for model in self.models for f in model.factors]

    @property
    def exploratory(self) -> list[Contrast]:
        """Every contrast but the declared hypothesis's."""
        return [c for c in self.contrasts if c.exploratory]

    def hypothesis_sentences(self) -> list[str]:
        """Say the confirmatory test of each primary measure (none without a hypothesis)."""
        table = self.table
        return [
            confirmatory_sentence(t, table.label(t.measure), table.units(t.measure))
            for t in self.confirmatory or []
        ]

    def sentences(self) -> list[str]:
        """Say each exploratory comparison in a plain-language line."""
        table = self.table
        return [
            comparison_sentence(c, table.label(c.measure), table.units(c.measure))
            for c in self.exploratory
        ]

    def factor_sentences(self) -> list[str]:
        """Say each test of the partner's kind and of condition x kind in a line."""
        table = self.table
        return [
            factor_sentence(f, table.label(f.measure), table.units(f.measure)) for f in self.factors
        ]

    def verdict(self) -> str:
        """Return the report's first line."""
        labels = {measure: self.table.label(measure) for measure in self.table.outcomes}
        unconverged = [m.measure for m in self.models if m.random_effects and not m.converged]
        return verdict(self.exploratory, self.identification, self.confirmatory, labels,
                       unconverged)  # fmt: skip

    def results(self) -> dict[str, Any]:
        """Every number, for ``results.json``."""
        return {
            "verdict": self.verdict(),
            "hypothesis": self.hypothesis_sentences(),
            "confirmatory": None
            if self.confirmatory is None
            else [asdict(t) | _judged(t) for t in self.confirmatory],
            "sentences": self.sentences(),
            "methods": methods_paragraph(self.parameters),
            "parameters": self.parameters,
            "conditions": self.summaries.to_dict(orient="records"),
            "models": [asdict(model) for model in self.models],
            "identification": None
            if self.identification is None
            else self.identification.to_dict(),
            "notes": self.notes,
            "deviations_from_plan": self.deviations,
        }


def analyse_study(
    table: StudyTable,
    seed: int = 0,
    reference: str | None = None,
    resamples: int = BOOTSTRAP_RESAMPLES,
    confidence: float = CONFIDENCE,
    protocol: Protocol | None = None,
    plan: RegisteredPlan | None = None,
) -> StudyAnalysis:
    """Run every statistic on ``table``, the protocol's declared hypothesis first.

    Parameters
    ----------
    table
        The study table.
    seed
        Seed of the bootstrap's generator.
    reference
        The condition the others are compared with; default the hypothesis's reference, else
        the first condition (the protocol's first, else the dictionary's first level of
        ``condition``, else the first in the table).
    resamples, confidence
        Bootstrap resamples and the confidence level of every interval.
    protocol
        The study's protocol: its conditions' order and its ``[analysis]``, the hypothesis
        tested first (`mirror_avatar.analysis.hypothesis.confirm`); without one, or without an
        analysis, every comparison is exploratory.
    plan
        The registered plan the analysis is checked against (`plan_deviations`); the report is
        written whatever differs.

    Raises
    ------
    InputError
        ``reference`` is not a condition of the table; the hypothesis names a condition or a
        primary measure the table does not have.
    """
    conditions = _ordered_conditions(table, protocol)
    hypothesis = None if protocol is None else protocol.analysis
    if protocol is not None and hypothesis is not None:
        check_hypothesis(table, hypothesis, conditions, protocol.source)
    if reference is None:
        reference = conditions[0] if hypothesis is None else hypothesis.reference
    elif reference not in conditions:
        raise InputError("--reference", f"no condition {reference!r} in {table.source}; its "
                         f"conditions are {', '.join(conditions)}")  # fmt: skip
    rows, notes, incomplete = analysed_rows(table)
    if table.skipped_measures:
        notes.append(f"not numbers, so not averaged: {', '.join(table.skipped_measures)}")
    summaries = _summaries(rows, table.outcomes, conditions, seed, resamples, confidence)
    models, untested = [], []
    for measure in table.outcomes:
        model = (circular_contrasts(rows, measure, conditions, reference, seed) if is_angle(measure)
                 else fit_contrasts(rows, measure, conditions, reference, confidence))  # fmt: skip
        if model is None:
            untested.append(measure)
        else:
            models.append(model)
            notes += [f"{measure}: {note}" for note in model.notes]
    models = _with_factor_q_values(_with_q_values(models, hypothesis))
    notes += few_participants_note(int(rows["participant"].nunique()))
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
        "model": MIXED_MODEL, "confirmatory_model": (
            CONFIRMATORY_MODEL if hypothesis is None else confirmatory_model(hypothesis.primary)
        ),
        "random_effects": {table.label(m.measure): m.random_effects for m in models
                           if m.random_effects},
        "fixed_effects": {table.label(m.measure): m.fixed_effects for m in models
                          if m.fixed_effects},
        "angles": [table.label(m) for m in table.outcomes if is_angle(m)],
        "exploratory": EXPLORATORY_MODEL,
        "protocol": None if protocol is None else Path(protocol.source).name,
        "plan": None if plan is None else {"file": plan.source.name, "sha256": plan.sha256},
        "hypothesis": None if hypothesis is None else asdict(hypothesis),
        "identification": "persons' rates against 0.5 by a one-sample t-test over persons "
                          "(the verdict's; the pooled exact binomial when fewer than two "
                          "persons' rates differ); exact binomial of every answer against "
                          "0.5; d' and c with log-linear correction when a rate is 0 or 1; "
                          "Mann-Whitney U for confidence",
        "versions": _versions(),
    }  # fmt: skip
    return StudyAnalysis(
        table=table, rows=rows, conditions=conditions, reference=reference, summaries=summaries,
        models=models, identification=identify(rows, confidence), parameters=parameters,
        notes=notes, confirmatory=None if hypothesis is None else confirm(rows, hypothesis),
        deviations=None if plan is None else plan_deviations(plan, hypothesis),
    )  # fmt: skip


def _summaries(
    rows: pd.DataFrame,
    outcomes: list[str],
    conditions: list[str],
    seed: int,
    resamples: int,
    confidence: float,
) -> pd.DataFrame:
    """Summarise each outcome per condition: angles by circular statistics, the rest linearly.

    The columns of `condition_summaries`, then ``resultant_length`` and ``rayleigh_p``
    (`circular_summaries`; NaN for a measure that is not an angle), in the outcomes' order.
    """
    linear = [m for m in outcomes if not is_angle(m)]
    parts = [condition_summaries(rows, linear, conditions, seed, resamples, confidence)]
    parts += [pd.DataFrame(circular_summaries(rows, m, conditions))
              for m in outcomes if is_angle(m)]  # fmt: skip
    columns = ["measure", "condition", "participants", "mean", "ci_low", "ci_high", "sd",
               "resultant_length", "rayleigh_p"]  # fmt: skip
    joined = pd.concat([p.reindex(columns=columns) for p in parts if len(p)], ignore_index=True)
    order = {m: i for i, m in enumerate(outcomes)}
    return joined.sort_values("measure", key=lambda m: m.map(order), kind="stable").reset_index(
        drop=True
    )


def few_participants_note(participants: int) -> list[str]:
    """Warn, in the notes, of a study with fewer than `FEW_PARTICIPANTS` participants."""
    if participants >= FEW_PARTICIPANTS:
        return []
    return [
        f"only {participants} participants (fewer than {FEW_PARTICIPANTS}): every p-value here "
        "rests on normal distributions that so few participants cannot check (the Wilcoxon "
        f"cross-check cannot reach p < 0.05 with fewer than {FEW_PARTICIPANTS}), and the "
        "participants' variance, and so the degrees of freedom, are poorly estimated; read "
        "the tests as a pilot's, not as evidence"
    ]


def analysed_rows(table: StudyTable) -> tuple[pd.DataFrame, list[str], int | None]:
    """Return the rows every statistic uses, what was left out in words, and the incomplete rows.

    The persons' rows (avatars are not participants) of complete trials (a person screened out
    before their first trial has a row without one), every infinite value
    of an outcome made missing; the count of incomplete rows left out is None when the table
    has no ``complete`` column.

    Raises
    ------
    InputError
        Every row is of an incomplete trial.
    """
    rows, notes = _participants_rows(table.rows)
    rows, refused = _played_rows(rows)
    rows, incomplete = _complete_rows(rows, table.source)
    notes += refused + _incomplete_note(incomplete)
    rows, left_out = _finite(rows, table.outcomes)
    return rows, notes + left_out, incomplete


def _ordered_conditions(table: StudyTable, protocol: Protocol | None) -> list[str]:
    """List the table's conditions, in the protocol's order when one is given (the rest after)."""
    found = table.conditions()
    if protocol is None:
        return found
    ordered = [c for c in protocol.conditions if c in found]
    return ordered + [c for c in found if c not in ordered]


def check_hypothesis(
    table: StudyTable, hypothesis: Analysis, conditions: list[str], source: str
) -> None:
    """Refuse a hypothesis about conditions or measures the table does not have.

    ``source``: the protocol's file, named in the error.
    """
    for condition in (hypothesis.condition, hypothesis.reference):
        if condition not in conditions:
            raise InputError(source, f"analysis: no condition {condition!r} in {table.source}; "
                             f"its conditions are {', '.join(conditions)}")  # fmt: skip
    missing = [m for m in hypothesis.primary if m not in table.outcomes]
    if missing:
        raise InputError(source, f"analysis.primary: no measure {', '.join(missing)} in "
                         f"{table.source} (a measure of a pair or a group only?)")  # fmt: skip


def _with_q_values(models: list[MeasureModel], hypothesis: Analysis | None) -> list[MeasureModel]:
    """Mark the hypothesis's contrasts, and give every other its Benjamini-Hochberg q-value.

    A confirmatory contrast enters as NaN: left out of the count, its q NaN.
    """
    p = [np.nan if _is_confirmatory(c, hypothesis) else c.p for m in models for c in m.contrasts]
    q = iter(benjamini_hochberg(p))
    return [
        replace(model, contrasts=[
            replace(c, exploratory=not _is_confirmatory(c, hypothesis), q=float(next(q)))
            for c in model.contrasts
        ]) for model in models
    ]  # fmt: skip


def _with_factor_q_values(models: list[MeasureModel]) -> list[MeasureModel]:
    """Give every test of kind and condition x kind its Benjamini-Hochberg q across the study's."""
    q = iter(benjamini_hochberg([f.p for m in models for f in m.factors]))
    return [replace(m, factors=[replace(f, q=float(next(q))) for f in m.factors]) for m in models]


def _is_confirmatory(contrast: Contrast, hypothesis: Analysis | None) -> bool:
    return hypothesis is not None and (
        contrast.measure in hypothesis.primary
        and (contrast.condition, contrast.reference) == (hypothesis.condition, hypothesis.reference)
    )


def _judged(test: ConfirmatoryTest) -> dict[str, bool]:
    """Say what a confirmatory test concluded, for ``results.json``."""
    return {"significant": test.significant, "exceeds_smallest_effect": test.exceeds_smallest,
            "supported": test.supported}  # fmt: skip


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
        "protocol": analysis.parameters["protocol"] or "none given",
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


def _played_rows(rows: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Leave out the rows of persons screened out before their first trial (no trial)."""
    if "trial" not in rows:
        return rows, []
    played = rows[rows["trial"].notna()]
    left = len(rows) - len(played)
    return played, [
        f"{left} rows of persons screened out before their first trial left out"
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
               "condition_mean", "difference", "ci_low", "ci_high", "df", "p", "p_holm",
               "exploratory", "q", "standardised", "d_z", "t", "t_p", "wilcoxon_p"]  # fmt: skip
    return pd.DataFrame([asdict(c) for c in analysis.contrasts], columns=columns)


def _heading(table: StudyTable, column: str) -> str:
    """Name a column in words with its units: ``RMSE (playing range units)``."""
    units = table.units(column)
    return table.label(column) + ("" if units in NO_UNITS else f" ({units})")


def _contrast_displays(analysis: StudyAnalysis) -> dict[str, pd.DataFrame]:
    """Show the contrasts in two narrow tables: the model's, and the participants' means'."""
    table = _contrast_table(analysis)
    measures = table["measure"].map(lambda m: _heading(analysis.table, m))
    index = pd.MultiIndex.from_arrays([measures, table["condition"]],
                                      names=["measure", "condition"])  # fmt: skip
    interval = [f"{low:.4g} to {high:.4g}" for low, high in zip(table["ci_low"], table["ci_high"],
                                                               strict=True)]  # fmt: skip
    model = {
        "test": table["exploratory"].map({True: "exploratory", False: "confirmatory"}),
        "difference": table["difference"], "95 % CI": interval, "df": table["df"].round(1),
        "p": table["p"].map(_p_cell), "q (BH)": table["q"].map(_p_cell),
        "p Holm": table["p_holm"].map(_p_cell), "standardised": table["standardised"],
    }  # fmt: skip
    paired = {
        "n": table["participants"], analysis.reference: table["reference_mean"],
        "condition": table["condition_mean"], "d_z": table["d_z"],
        "t-test p": table["t_p"].map(_p_cell), "Wilcoxon p": table["wilcoxon_p"].map(_p_cell),
    }  # fmt: skip
    return {
        f"Mixed model: each condition's difference from {analysis.reference!r} (measure units), "
        "its 95 % CI, the t test's Satterthwaite degrees of freedom, p, q (p adjusted by "
        "Benjamini-Hochberg across every exploratory comparison), p Holm-corrected over a "
        "measure's contrasts, and the difference over the model's SD": pd.DataFrame(
            model
        ).set_index(index),
        "Participants' means: the reference's and the condition's, Cohen's d_z, paired t-test "
        "and Wilcoxon signed-rank test": pd.DataFrame(paired).set_index(index),
    }


def _factor_table(analysis: StudyAnalysis) -> pd.DataFrame:
    """Show the tests of the partner's kind and of condition x kind, a row each."""
    return pd.DataFrame([{
        "measure": _heading(analysis.table, f.measure), "term": f.term,
        "compared": f"{f.kind} against {f.reference_kind}"
                    + (f", {f.condition}'s effect" if f.condition else ""),
        "estimate": f.estimate, "95 % CI": f"{f.ci_low:.4g} to {f.ci_high:.4g}",
        "df": round(f.df, 1), "p": _p_cell(f.p), "p Holm": _p_cell(f.p_holm),
        "q (BH)": _p_cell(f.q),
    } for f in analysis.factors]).set_index("measure")  # fmt: skip


def _p_cell(p: float) -> str:
    return format_p(p).removeprefix("p = ").removeprefix("p ")


def _model_table(analysis: StudyAnalysis) -> pd.DataFrame:
    return pd.DataFrame([{
        "measure": _heading(analysis.table, m.measure), "trials": m.rows,
        "participants": m.participants, "random effects": m.random_effects or "not fitted",
        "order slope per position": m.position_slope,
        "order p": m.position_p, "participant variance": m.participant_variance,
        "partner variance": m.partner_variance,
        "residual variance": m.residual_variance,
    } for m in analysis.models]).set_index("measure")  # fmt: skip


def plan_lines(deviations: list[str] | None) -> list[str]:
    """Say how the analysis run follows the registered plan: nothing when no plan was given."""
    if deviations is None:
        return []
    if not deviations:
        return ["The analysis run follows the registered plan."]
    return [f"Deviation from the registered plan: {line}." for line in deviations]


def _hypothesis_section(analysis: StudyAnalysis) -> Section:
    """Show the declared hypothesis's test first: its result per primary measure."""
    plan = plan_lines(analysis.deviations)
    if analysis.confirmatory is None:
        text = ["No hypothesis was declared (no [analysis] in the protocol, or no --protocol "
                "given): every comparison below is exploratory.", *plan]  # fmt: skip
        return Section("hypothesis", "Confirmatory test", text=text)
    tests = pd.DataFrame([{
        "measure": _heading(analysis.table, t.measure), "condition": t.condition,
        "reference": t.reference, "direction": t.direction, "n": t.participants,
        "difference": number(t.estimate),
        f"{t.confidence:.0%} CI": f"{number(t.ci_low)} to {number(t.ci_high)}",
        "test": t.test, "p": _p_cell(t.p), "p Holm": _p_cell(t.p_holm), "alpha": f"{t.alpha:g}",
        "smallest effect": f"{t.smallest_effect:g}",
        "reaches it": "yes" if t.exceeds_smallest else "no",
        "supported": "yes" if t.supported else "no",
    } for t in analysis.confirmatory]).set_index("measure")  # fmt: skip
    if len(tests) == 1:
        tests = tests.drop(columns="p Holm")  # one primary measure: nothing to correct
    return Section("hypothesis", "Confirmatory test: the declared hypothesis",
                   text=[*analysis.hypothesis_sentences(), *plan],
                   tables={"The declared test of the participants' means, condition minus "
                           "reference": tests})  # fmt: skip


def _sections(analysis: StudyAnalysis) -> list[Section]:
    table = analysis.table
    summaries = analysis.summaries.assign(
        measure=analysis.summaries["measure"].map(lambda m: _heading(table, m))
    ).set_index(["measure", "condition"])
    figures = {
        f"{table.label(measure)}: each participant's mean per condition (grey lines), the mean "
        f"over participants with its {analysis.parameters['confidence']:.0%} bootstrap CI": (
            plot_participants(
                participant_means(
                    analysis.rows,
                    measure,
                    analysis.conditions,
                    circular_mean if is_angle(measure) else "mean",
                ),  # fmt: skip
                analysis.summaries[analysis.summaries["measure"] == measure],
                _heading(table, measure),
            )
        )
        for measure in table.outcomes
    }
    exploratory = ("Exploratory: every comparison below but the declared hypothesis's, its "
                   "p-value adjusted for the false discovery rate across measures "
                   "(Benjamini-Hochberg q-values).")  # fmt: skip
    sections = [
        _hypothesis_section(analysis),
        Section("comparisons", "Exploratory comparisons",
                text=[exploratory, *analysis.sentences(), *analysis.factor_sentences(),
                      *analysis.notes]),
        Section("conditions", "Each condition: mean over participants and its CI",
                tables={"Mean, bootstrap CI and SD of the participants' means": summaries},
                figures=figures),
        Section("contrasts", "Contrasts within participants (mixed models)", tables={
            **_contrast_displays(analysis),
            "Each measure's random effects, order (position in the participant's order) and "
            "variances": _model_table(analysis),
            **({"Partner kind: each kind's difference from the reference kind over the "
                "conditions, and each condition's effect with the kind minus with the reference "
                "kind (measure units), Satterthwaite t tests; p Holm-corrected within the "
                "measure's term, q across every test of kind": _factor_table(analysis)}
               if analysis.factors else {}),
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
