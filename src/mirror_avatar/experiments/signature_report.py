"""The report of ``mirror-avatar signature``: are the people told apart, how well, and how.

`signature_page` renders one self-contained HTML page (`mirror_avatar.report`) that leads with
the verdict (`mirror_avatar.signatures.identification`, and with ``--groups`` the comparison of
the two groups, `mirror_avatar.signatures.groups`), then shows the similarity space and the EMD
between trials, then the signatures and strokes. The figures are the PNG files the command
writes beside it.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from typing import Any

import pandas as pd

from mirror_avatar.experiments.signature import compute_within_between, stroke_table
from mirror_avatar.figures.signatures import HUMAN_KURTOSIS, HUMAN_SKEWNESS
from mirror_avatar.report import Section, render_report
from mirror_avatar.signatures.groups import GroupComparison
from mirror_avatar.signatures.identification import Identification
from mirror_avatar.signatures.signature import SignatureAnalysis

TITLE = "mirror-avatar: motor signatures"

CAPTIONS = {
    "similarity.png": "Similarity space (classical MDS of the EMD between trials): each person's "
    "trials in their colour, their name near the centre of them, their region when they have 3 "
    "trials or more",
    "distances.png": "EMD between every two trials, grouped by person (dark: alike)",
    "groups.png": "The two groups: their people in the similarity space (crosses: classified "
    "into the other group), and each test against labels shuffled by person",
    "ims.png": "Velocity signature (IMS) of each person, their trials pooled",
    "strokes.png": "Skewness and kurtosis of each velocity stroke (dashed: the human range)",
}
"""Caption of each figure file in the report."""

NO_IDENTIFICATION = (
    "No identification: it needs two people or more, one of them with two trials or more."
)


def signature_page(
    analysis: SignatureAnalysis,
    identification: Identification | None,
    figures: Mapping[str, bytes],
    comparison: GroupComparison | None = None,
    metadata: Mapping[str, Any] | None = None,
) -> str:
    """Render the report's HTML page.

    Parameters
    ----------
    analysis
        The signature analysis; its groups are the people.
    identification
        Each trial put with its nearest person (None when that is not possible).
    figures
        PNG bytes of each figure file (keys of `CAPTIONS`; ``groups.png`` with a comparison).
    comparison
        The two groups compared (``--groups``), or None.
    metadata
        What the run was (version, command, seed...).
    """
    verdict = identification.verdict() if identification else NO_IDENTIFICATION
    sections = [_people_section(analysis, identification, verdict, figures)]
    lead = verdict
    if comparison is not None:
        lines = comparison.verdict()
        lead = f"{verdict} Groups: {lines[0]}."
        sections.append(
            Section(
                key="groups",
                title=f"The two groups: {' and '.join(comparison.groups)}",
                verdict=lines[0],
                text=[*lines[1:], _GROUP_METHOD],
                figures={CAPTIONS["groups.png"]: figures["groups.png"]},
            )
        )
    sections.append(_signature_section(analysis, figures))
    return render_report(sections, TITLE, metadata, lead=lead)


def _people_section(
    analysis: SignatureAnalysis,
    identification: Identification | None,
    verdict: str,
    figures: Mapping[str, bytes],
) -> Section:
    within, between = compute_within_between(analysis)
    sizes = Counter(analysis.groups)
    alone = [person for person in analysis.group_names if sizes[person] == 1]
    text = [
        f"{len(analysis.labels)} trials of {len(analysis.group_names)} people (a person: the "
        f"trials --group-by puts together), resampled to {analysis.rate:g} Hz. Each trial in "
        "turn is put with the person whose other trials are nearest on average (mean EMD of "
        "their velocity signatures); chance is the same share with the trials' person labels "
        "shuffled.",
        f"Mean EMD between two trials of one person {within:.4f}, of two people {between:.4f}"
        + (f" ({between / within:.1f} x)" if within > 0 else "")
        + ". The literature's range: one person 0.002-0.025, two people 0.01-0.1.",
    ]
    if alone:
        text.append(
            f"{len(alone)} of the people have one trial only ({', '.join(alone[:5])}"
            f"{', ...' if len(alone) > 5 else ''}): they are candidates, but cannot be "
            "identified themselves."
        )
    tables = {}
    if identification is not None:
        tables["Each person's trials: how many were put with them, and with whom otherwise"] = (
            _person_table(identification, sizes)
        )
    return Section(
        key="people",
        title="Are the people told apart?",
        verdict=verdict,
        text=text,
        tables=tables,
        figures={CAPTIONS[name]: figures[name] for name in ("similarity.png", "distances.png")},
        metrics={} if identification is None else identification.to_json_dict(),
    )


def _person_table(identification: Identification, sizes: Counter[str]) -> pd.DataFrame:
    rows = {}
    for person in identification.people:
        guesses = [
            guess
            for truth, guess in zip(identification.truth, identification.predicted, strict=True)
            if truth == person
        ]
        wrong = Counter(guess for guess in guesses if guess != person)
        rows[person] = {
            "trials": sizes[person],
            "put with them": f"{len(guesses) - sum(wrong.values())} of {len(guesses)}"
            if guesses
            else "-",
            "put with another": ", ".join(f"{name} ({n})" for name, n in wrong.most_common())
            or "-",
        }
    return pd.DataFrame.from_dict(rows, orient="index")


def _signature_section(analysis: SignatureAnalysis, figures: Mapping[str, bytes]) -> Section:
    bins = analysis.bins
    return Section(
        key="signatures",
        title="Velocity signatures and strokes",
        text=[
            f"The IMS is the histogram of velocity on {bins.n} bins over [{bins.lo:g}, "
            f"{bins.hi:g}] units/s; the EMD between two of them is normalised by the bin range "
            "(0 to 1). A stroke is the motion between two reversals; people's strokes have "
            f"skewness in {HUMAN_SKEWNESS} and kurtosis in {HUMAN_KURTOSIS} (METHODS section 3)."
        ],
        tables={"Velocity strokes of each person": stroke_table(analysis)},
        figures={CAPTIONS[name]: figures[name] for name in ("ims.png", "strokes.png")},
    )


_GROUP_METHOD = (
    "People are the units: the distance between two people is the mean EMD between their "
    "trials; each person, left out in turn, is put in the group whose people are nearer on "
    "average; labels are shuffled by person for chance (METHODS section 3, groups of people)."
)
