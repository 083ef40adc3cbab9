"""The partner's kind as a fixed factor of the mixed model, and condition x kind (METHODS 15.5).

A blinded study shows each participant partners of several true kinds (a person, a computer
player, a person's recorded trial replayed: the table's ``partner_kind``); whether a measure
differs by kind, and whether a condition's effect does, are the questions such a study exists
for. `kind_terms` adds the kind to a measure's fixed effects when its trials have more than one
kind, with condition x kind where the design can tell it apart, each term coded so that the
condition's contrasts keep their meaning: the kinds by centred indicators and the interactions
by products of centred codes (weighted-effects coding; Cohen, Cohen, West & Aiken 2003,
*Applied Multiple Regression/Correlation Analysis*, ch. 8), so that a condition's coefficient
is its effect averaged over the kinds (weighted by their trials), a kind's its difference from
the reference kind averaged over the conditions, and an interaction the difference of a
condition's effect between the two kinds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from mirror_avatar.analysis.dictionary import DESIGN_COLUMNS

KIND_ORDER = tuple(DESIGN_COLUMNS["partner_kind"]["Levels"])
"""The kinds in the dictionary's order: the first present is the reference kind."""

KIND_TERM = "partner kind"
INTERACTION_TERM = "condition x partner kind"
"""The two terms, in words."""


@dataclass(frozen=True)
class KindTerms:
    """The design with the kind's columns, and what each tests.

    Parameters
    ----------
    design
        The fixed effects (N x p), the kind's columns after the given ones.
    reference
        The reference kind; "" when the trials have one kind.
    columns
        Each added column -> (term, condition, kind), in design order: the condition "" for
        a kind's own column.
    notes
        What was left out and why, in plain words.
    """

    design: pd.DataFrame
    reference: str
    columns: dict[str, tuple[str, str, str]]
    notes: list[str]


def kind_column(kind: str) -> str:
    """Name a kind's column in the design."""
    return f"partner_kind[{kind}]"


def interaction_column(condition: str, kind: str) -> str:
    """Name a condition x kind column in the design."""
    return f"{condition}:partner_kind[{kind}]"


def ordered_kinds(kinds: pd.Series) -> list[str]:
    """List the kinds present, in `KIND_ORDER`, then any other in sorted order."""
    present = set(kinds.dropna().astype(str))
    return [k for k in KIND_ORDER if k in present] + sorted(present - set(KIND_ORDER))


def kind_terms(
    design: pd.DataFrame, kinds: pd.Series, conditions: pd.Series, others: list[str]
) -> KindTerms:
    """Add the partner's kind, and condition x kind, to ``design`` where the trials allow.

    Parameters
    ----------
    design
        The fixed effects (N x p): ``Intercept``, a dummy per non-reference condition in
        ``others``, then any covariates.
    kinds, conditions
        Each trial's partner kind and condition (N).
    others
        The non-reference conditions, whose dummies are in ``design``.

    A kind k other than the reference gets z_k = [kind is k] - its mean over the trials; each
    pair of a non-reference condition c and such a kind gets (d_c - mean d_c) z_k. The
    interactions are added when the design keeps full rank with them (each kind met in two
    conditions or more), else left out with a note; then the kinds likewise (a kind the
    condition fixes, as in a design whose conditions are the partners' kinds, is the
    condition's contrast, not a factor apart).
    """
    levels = ordered_kinds(kinds)
    if len(levels) < 2:
        return KindTerms(design, "", {}, [])
    reference, tested = levels[0], levels[1:]
    centred = {k: (kinds == k).astype(np.float64) - float((kinds == k).mean()) for k in tested}
    main = pd.DataFrame({kind_column(k): centred[k] for k in tested}, index=design.index)
    products = pd.DataFrame({
        interaction_column(c, k): ((conditions == c).astype(np.float64)
                                   - float((conditions == c).mean())) * centred[k]
        for c in others for k in tested
    }, index=design.index)  # fmt: skip
    words = {kind_column(k): (KIND_TERM, "", k) for k in tested}
    words |= {interaction_column(c, k): (INTERACTION_TERM, c, k) for c in others for k in tested}
    full = pd.concat([design, main, products], axis=1)
    if _full_rank(full):
        return KindTerms(full, reference, words, [])
    with_kind = pd.concat([design, main], axis=1)
    if _full_rank(with_kind):
        note = (f"{INTERACTION_TERM} not tested: the kinds were not each met in two conditions "
                "or more")  # fmt: skip
        return KindTerms(with_kind, reference, {c: words[c] for c in main.columns}, [note])
    note = f"{KIND_TERM} not tested apart from condition: the condition fixes the partner's kind"
    return KindTerms(design, reference, {}, [note])


def _full_rank(design: pd.DataFrame) -> bool:
    return bool(np.linalg.matrix_rank(design.to_numpy(np.float64)) == design.shape[1])
