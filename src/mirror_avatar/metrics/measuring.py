"""How a session is measured: one trim, one analysis rate, one seed rule (METHODS section 12).

`measure_sessions` is what ``evaluate`` calls, and `measure_trial` (one session) what
``study table`` and the lab's own analysis of a trial (its sidecar, the console's row, the end
screens) call, so that a trial's numbers are the same
wherever they are read:

- the session is brought to the analysis rate (`mirror_avatar.metrics.analysis_rate`), then its
  first ``trim`` seconds (`mirror_avatar.metrics.summary.TRIM` by default) are left out
  (`analysed`);
- its metrics (`mirror_avatar.metrics.summary.session_metrics`) and measures
  (`mirror_avatar.metrics.measures.session_measures`) share one `Quantities`;
- its surrogates are drawn from the seed the session records (``metadata["seed"]``: a lab
  trial's, a simulated session's), whatever else is measured with it (`surrogate_seed`); session
  i of those that record none draws them from child i of the options' seed
  (`mirror_avatar.common.seeds.spawn_seeds`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from tqdm.auto import tqdm

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import spawn_seeds
from mirror_avatar.files.trials import MIN_SAMPLES
from mirror_avatar.metrics.analysis_rate import at_analysis_rate
from mirror_avatar.metrics.measures import (
    CONSTRAINTS,
    MeasureOptions,
    Measures,
    session_measures,
    weak_null_of,
)
from mirror_avatar.metrics.quantities import Quantities
from mirror_avatar.metrics.summary import TRIM, session_metrics
from mirror_avatar.metrics.surrogates import WeakNull
from mirror_avatar.sessions.session import Session

TRIAL_SURROGATES = 19
"""Surrogates per lab trial (**choice**): enough for a p-value of 0.05 (the smallest that 19
give: the measure beat every surrogate) at a fraction of a second per minute of trial, so the
lab's end screens come at once; ``study table`` draws as many by default, and
``mirror-avatar evaluate --surrogates`` gives finer p-values later."""

SEEDS = CONSTRAINTS["seed"]
"""The seeds surrogates may be drawn from."""


@dataclass(frozen=True)
class Measured:
    """A session as measured.

    Attributes
    ----------
    session
        The session analysed: at the analysis rate, its first ``trim`` seconds left out.
    metrics
        `mirror_avatar.metrics.summary.session_metrics` of it.
    measures
        `mirror_avatar.metrics.measures.session_measures` of it.
    quantities
        The quantities both share.
    """

    session: Session
    metrics: dict[str, Any]
    measures: Measures
    quantities: Quantities


def analysed(session: Session, trim: float = TRIM) -> Session:
    """Return ``session`` as it is measured: at the analysis rate, then ``trim`` (s) left out.

    Raises
    ------
    mirror_avatar.common.errors.InputError
        A ``trim`` that leaves fewer than two samples.
    """
    at_rate = at_analysis_rate(session)
    return at_rate.trimmed(trim) if trim > 0 else at_rate


def surrogate_seed(session: Session, otherwise: int) -> int:
    """Return the seed of a session's surrogates: the one it records, else ``otherwise``.

    A recorded seed outside the surrogates' range (`mirror_avatar.metrics.measures.CONSTRAINTS`)
    counts as none.
    """
    recorded = session.metadata.get("seed")
    if isinstance(recorded, int) and not isinstance(recorded, bool) and recorded in SEEDS:
        return recorded
    return otherwise


def measure_sessions(
    sessions: Sequence[Session], options: MeasureOptions, trim: float = TRIM
) -> tuple[list[Measured], WeakNull | None]:
    """Measure sessions as the module docstring says, and test their synchrony together.

    Pseudo-pair surrogates take their partners from the other sessions, analysed alike. A
    progress bar shows on a terminal when surrogates are drawn.

    Parameters
    ----------
    sessions
        The sessions as recorded.
    options
        The measures' options; its ``seed`` seeds the sessions that record none.
    trim
        Seconds left out at the start (s).

    Returns
    -------
    measured, weak_null
        Each session measured, in order; the weak-null test of their synchrony
        (`mirror_avatar.metrics.measures.weak_null_of`).
    """
    kept = [analysed(session, trim) for session in sessions]
    return _measured(kept, options)


def measure_trial(
    session: Session, surrogates: int = TRIAL_SURROGATES, trim: float = TRIM
) -> Measured | None:
    """Measure one trial as `measure_sessions` does, with ``surrogates`` circular shifts.

    Returns
    -------
    Measured or None
        None when fewer than `mirror_avatar.files.trials.MIN_SAMPLES` samples remain after the trim
        (a trial stopped at once).
    """
    kept = measurable(session, trim)
    if kept is None:
        return None
    return _measured([kept], MeasureOptions(n_surrogates=surrogates))[0][0]


def measurable(session: Session, trim: float = TRIM) -> Session | None:
    """Return the session as it is measured (`analysed`), or None when it is too short to be.

    None when fewer than `mirror_avatar.files.trials.MIN_SAMPLES` samples remain after the trim.
    """
    try:
        kept = analysed(session, trim)
    except InputError:
        return None
    return kept if kept.n_samples >= MIN_SAMPLES else None


def _measured(
    kept: list[Session], options: MeasureOptions
) -> tuple[list[Measured], WeakNull | None]:
    """Measure sessions already analysed (`measure_sessions`)."""
    children = spawn_seeds(options.seed, len(kept))
    quantities = [Quantities.of(session) for session in kept]
    measured = []
    shown = tqdm(list(zip(kept, quantities, strict=True)), unit="session", leave=False,
                 disable=None if options.n_surrogates > 0 else True)  # fmt: skip
    for i, (session, q) in enumerate(shown):
        seeded = replace(options, seed=surrogate_seed(session, int(children[i])))
        partners = kept[:i] + kept[i + 1 :]
        measures = session_measures(session, 0.0, seeded, partners, quantities=q)
        measured.append(Measured(session, session_metrics(session, quantities=q), measures, q))
    return measured, weak_null_of(quantities)
