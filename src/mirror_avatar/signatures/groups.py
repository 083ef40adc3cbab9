"""Two groups of people compared by their motor signatures (METHODS section 3, groups of people).

After Słowiński et al. (npj Schizophrenia 2017), who told patients from controls by their
mirror-game motion: here by the velocity IMS alone. People are the units throughout (a person's
trials are never split between training and test, and labels are permuted by person):

- The distance between two people is the mean EMD between the IMS of their trials.
- **Between- vs within-group distance**: the mean over pairs of people in different groups, the
  mean over pairs in one group, and a permutation test of their difference.
- **Classification**: each person in turn is left out and put in the group whose people are
  nearer on average (leave-one-person-out); accuracy, sensitivity (the second group, as the file
  names it, is the positive one) and specificity, each beside its label-shuffled chance, the
  accuracy with a permutation p-value.
- **The classifier two-sample test** of the human-likeness battery
(`mirror_avatar.signatures.likeness`) on
  windows of the two groups' trials, folds and permutations grouped by person.

The groups come from a table (`read_group_map`) naming people or trials.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import draw_seeds
from mirror_avatar.files.importing import excerpt
from mirror_avatar.files.trial_io import read_sidecar_text
from mirror_avatar.files.trials import DEFAULT_RATE, Trial
from mirror_avatar.signatures.likeness import ClassifierTest, classifier_test
from mirror_avatar.signatures.permutations import (
    PermutationTest,
    between_and_within,
    between_minus_within,
    permutation_test,
)
from mirror_avatar.signatures.signature import classical_mds

Array = NDArray[np.float64]

ALPHA = 0.05
"""A p-value below this calls the groups different (**choice**)."""

GROUP_PERMUTATIONS = 2000
"""Relabellings of people per test (**choice**: a relabelling costs a leave-one-out pass over the
people's distances, microseconds, so p-values resolve 0.0005)."""


@dataclass(frozen=True)
class GroupMap:
    """Who is in which group, as a ``--groups`` table says.

    Attributes
    ----------
    path
        The table's file.
    by_trial
        Trial label -> (its person, or None when the table has no person column; its group).
    by_person
        Person -> group.
    order
        The groups in order of first appearance.
    """

    path: Path
    by_trial: dict[str, tuple[str | None, str]]
    by_person: dict[str, str]
    order: list[str]

    @property
    def trials_as_people(self) -> bool:
        """Whether some trial rows name no person, so that each of those trials is one."""
        return any(person is None for person, _ in self.by_trial.values())


def read_group_map(path: Path) -> GroupMap:
    """Read a CSV or TSV table with a ``group`` column and a ``person`` or ``trial`` column.

    A row naming a person puts all their trials (the trials grouped into that person by
    ``--group-by``) in the group; a row naming a trial puts that trial there, its person given by
    a ``person`` column of the same row or, without one, the trial itself (each trial then counts
    as one person). Tab-separated when the header line has a tab.

    Raises
    ------
    InputError
        Not UTF-8 or too large, columns missing, an empty cell, or a name in two groups.
    """
    text = read_sidecar_text(path)
    delimiter = "\t" if "\t" in text.partition("\n")[0] else ","
    try:
        reader = csv.DictReader(io.StringIO(text), delimiter=delimiter)
        rows = [{k.strip().lower(): (v or "").strip() for k, v in r.items() if k} for r in reader]
    except csv.Error as error:
        raise InputError(path, f"--groups is not a valid CSV or TSV table ({error})") from None
    columns = {c.strip().lower() for c in reader.fieldnames or []}
    if "group" not in columns or not columns & {"person", "trial"}:
        raise InputError(path, "--groups needs a column group and a column person or trial")
    by_trial: dict[str, tuple[str | None, str]] = {}
    by_person: dict[str, str] = {}
    for number, row in enumerate(rows, start=2):
        group, trial, person = row.get("group", ""), row.get("trial", ""), row.get("person", "")
        if not group or not (trial or person):
            raise InputError(path, f"row {number} has an empty cell: every row needs a group")
        if trial:
            _add(path, by_trial, trial, (person or None, group), "trial")
        else:
            _add(path, by_person, person, group, "person")
    order = list(dict.fromkeys(row["group"] for row in rows))
    return GroupMap(path, by_trial, by_person, order)


def _add(path: Path, table: dict[str, Any], key: str, value: Any, kind: str) -> None:
    if table.setdefault(key, value) != value:
        raise InputError(path, f"{kind} {excerpt(key)} is given twice with different groups")


def place_trials(
    trials: Sequence[Trial], labels: Sequence[str], groups: GroupMap
) -> tuple[list[str], list[str]]:
    """Return each trial's person and group, as ``groups`` says.

    Parameters
    ----------
    trials, labels
        The trials and their distinct labels (`mirror_avatar.signatures.signature.distinct_labels`).
    groups
        The table; a trial's own row wins over its person's (``trial.group``).

    Raises
    ------
    InputError
        A trial the table does not place, a person in both groups, other than two groups, or a
        group with fewer than two people.
    """
    people, placed = [], []
    for trial, label in zip(trials, labels, strict=True):
        if label in groups.by_trial:
            person, group = groups.by_trial[label]
            people.append(person or label)
        elif trial.group in groups.by_person:
            people.append(trial.group)
            group = groups.by_person[trial.group]
        else:
            raise InputError(
                groups.path,
                f"trial {excerpt(label)} (person {excerpt(trial.group)}) is not in --groups: "
                "add a row for the person or the trial",
            )
        placed.append(group)
    _check_groups(groups.path, people, placed)
    return people, placed


def _check_groups(path: Path, people: list[str], placed: list[str]) -> None:
    member: dict[str, str] = {}
    for person, group in zip(people, placed, strict=True):
        if member.setdefault(person, group) != group:
            raise InputError(path, f"person {excerpt(person)} has trials in two groups")
    names = sorted(set(placed))
    if len(names) != 2:
        raise InputError(
            path,
            f"the trials fall in {len(names)} group(s) ({', '.join(map(excerpt, names))}): "
            "--groups compares two",
        )
    for name in names:
        count = sum(group == name for group in member.values())
        if count < 2:
            raise InputError(
                path, f"group {excerpt(name)} has {count} person: each group needs at least 2"
            )


def person_distances(trial_distances: Array, people: Sequence[str]) -> tuple[list[str], Array]:
    """Mean distance between the trials of each pair of people.

    Parameters
    ----------
    trial_distances
        Distances between trials, shape (m, m).
    people
        Each trial's person, length m.

    Returns
    -------
    tuple
        The people in order of first appearance (length n) and their distances, shape (n, n),
        zero diagonal.
    """
    names = list(dict.fromkeys(people))
    index = np.array([names.index(p) for p in people])
    n = len(names)
    distances = np.zeros((n, n))
    for a in range(n):
        for b in range(a + 1, n):
            block = trial_distances[np.ix_(index == a, index == b)]
            distances[a, b] = distances[b, a] = float(block.mean())
    return names, distances


@dataclass(frozen=True)
class Classification:
    """Leave-one-person-out classification and its rates (shares in [0, 1]).

    Attributes
    ----------
    predicted
        Each person's predicted side (True: the positive group).
    accuracy, sensitivity, specificity
        Share of all people, of the positive group and of the other group classified right.
    """

    predicted: NDArray[np.bool_]
    accuracy: float
    sensitivity: float
    specificity: float


def classify_people(distances: Array, positive: NDArray[np.bool_]) -> Classification:
    """Put each person, left out in turn, in the group whose other people are nearer on average.

    Parameters
    ----------
    distances
        Distances between people, shape (n, n).
    positive
        Each person's side, shape (n,); each side at least two people.
    """
    n = positive.size
    predicted = np.empty(n, dtype=bool)
    for i in range(n):
        others = np.arange(n) != i
        to_positive = distances[i, others & positive].mean()
        to_negative = distances[i, others & ~positive].mean()
        predicted[i] = to_positive < to_negative
    right = predicted == positive
    return Classification(
        predicted,
        float(right.mean()),
        float(right[positive].mean()),
        float(right[~positive].mean()),
    )


@dataclass(frozen=True)
class GroupComparison:
    """Two groups of people compared (see the module docstring).

    Attributes
    ----------
    groups
        The two groups, the positive (for sensitivity) second.
    people, positive
        The people and whether each is in the positive group.
    distances
        Mean EMD between people, shape (n, n).
    coordinates
        Classical MDS of ``distances``, shape (n, 2).
    between, within
        Mean distance between people of different groups and of one group.
    separation
        Permutation test of ``between - within``, labels permuted by person.
    classification
        The leave-one-person-out classification with the true labels.
    chance
        Permutation test of the accuracy, labels permuted by person.
    chance_sensitivity, chance_specificity
        Mean sensitivity and specificity over those relabellings.
    classifier
        The classifier two-sample test of the groups' trials (None when no velocities given).
    seed
        Seed of the permutation tests.
    """

    groups: tuple[str, str]
    people: list[str]
    positive: NDArray[np.bool_]
    distances: Array
    coordinates: Array
    between: float
    within: float
    separation: PermutationTest
    classification: Classification
    chance: PermutationTest
    chance_sensitivity: float
    chance_specificity: float
    classifier: ClassifierTest | None
    seed: int

    def verdict(self) -> list[str]:
        """Return the distances, the classification and the classifier test, with verdicts."""
        negative, positive = self.groups
        counts = f"{negative} ({int((~self.positive).sum())} people) and {positive} " + (
            f"({int(self.positive.sum())} people)"
        )
        apart = self.separation.p_value < ALPHA
        c = self.classification
        return [
            f"{counts}: {'different' if apart else 'not told apart at this data size'}: "
            f"EMD between groups {self.between:.4f}, within {self.within:.4f} "
            f"(ratio {self.between / self.within:.2f}, {self.separation.p_words()})",
            f"classified {c.accuracy:.0%} right (sensitivity for {positive} "
            f"{c.sensitivity:.0%}, specificity {c.specificity:.0%}); label-shuffled chance "
            f"{np.mean(self.chance.null):.0%} ({self.chance_sensitivity:.0%}, "
            f"{self.chance_specificity:.0%}), {self.chance.p_words()}",
        ] + ([] if self.classifier is None else [f"trial windows: {self.classifier.verdict()}"])

    def to_json_dict(self) -> dict[str, Any]:
        """Return the comparison's numbers, verdict and seed."""
        c = self.classification
        return {
            "groups": list(self.groups),
            "positive_group": self.groups[1],
            "people": self.people,
            "person_groups": [self.groups[int(p)] for p in self.positive],
            "predicted_groups": [self.groups[int(p)] for p in c.predicted],
            "person_distances": self.distances.tolist(),
            "coordinates": self.coordinates.tolist(),
            "between": self.between,
            "within": self.within,
            "separation": self.separation.to_json_dict(),
            "accuracy": c.accuracy,
            "sensitivity": c.sensitivity,
            "specificity": c.specificity,
            "chance": self.chance.to_json_dict(),
            "chance_sensitivity": self.chance_sensitivity,
            "chance_specificity": self.chance_specificity,
            "classifier": None if self.classifier is None else self.classifier.to_json_dict(),
            "seed": self.seed,
            "verdict": self.verdict(),
        }


def compare_groups(
    trial_distances: Array,
    people: Sequence[str],
    groups: Sequence[str],
    order: Sequence[str],
    n_permutations: int = GROUP_PERMUTATIONS,
    seed: int = 0,
    velocities: Sequence[Array] | None = None,
    rate: float = DEFAULT_RATE,
) -> GroupComparison:
    """Compare two groups of people by the distances between their trials.

    Parameters
    ----------
    trial_distances
        Velocity IMS EMD between trials, shape (m, m).
    people, groups
        Each trial's person and group (`place_trials`), length m.
    order
        The groups in the table's order; the second present is the positive group.
    n_permutations, seed
        Of both permutation tests (labels permuted by person); the classifier test draws
        `mirror_avatar.signatures.likeness.N_PERMUTATIONS` relabellings.
    velocities, rate
        Each trial's velocity (units/s) at ``rate`` Hz, for the classifier test (none without).
    """
    names, distances = person_distances(trial_distances, people)
    group_of = dict(zip(people, groups, strict=True))
    present = [g for g in order if g in set(groups)]
    negative, positive_group = present[0], present[1]
    positive = np.array([group_of[p] == positive_group for p in names])
    separation_seed, chance_seed, classifier_seed = draw_seeds(seed, 3)
    between, within = between_and_within(distances, positive)
    results: list[Classification] = []

    def accuracy(side: NDArray[np.bool_]) -> float:
        results.append(classify_people(distances, side))
        return results[-1].accuracy

    chance = permutation_test(accuracy, positive, n_permutations, chance_seed)
    return GroupComparison(
        groups=(negative, positive_group),
        people=names,
        positive=positive,
        distances=distances,
        coordinates=classical_mds(distances, 2),
        between=between,
        within=within,
        separation=permutation_test(
            lambda side: between_minus_within(distances, side),
            positive,
            n_permutations,
            separation_seed,
        ),
        classification=results[0],
        chance=chance,
        chance_sensitivity=float(np.mean([r.sensitivity for r in results[1:]])),
        chance_specificity=float(np.mean([r.specificity for r in results[1:]])),
        classifier=None
        if velocities is None
        else _classifier(velocities, people, groups, positive_group, rate, classifier_seed),
        seed=seed,
    )


def _classifier(
    velocities: Sequence[Array],
    people: Sequence[str],
    groups: Sequence[str],
    positive: str,
    rate: float,
    seed: int,
) -> ClassifierTest:
    """Run the classifier two-sample test on the groups' trials, grouped by person."""
    side = [g == positive for g in groups]
    order = [k for k in range(len(side)) if not side[k]] + [k for k in range(len(side)) if side[k]]
    n_negative = side.count(False)
    signals = [velocities[k] for k in order]
    return classifier_test(
        signals[:n_negative],
        signals[n_negative:],
        rate,
        seed=seed,
        units=[people[k] for k in order],
    )
