"""The IMS generator's hyper-parameters, declared once as data (`mirror_avatar.common.constraints`).

`GENERATOR_SETTINGS` states each hyper-parameter of `mirror_avatar.motion.generator.IMSGenerator`:
what it sets, what it allows and its default. The constructor's values and a model file's are
checked against it (`check_hyperparameters`), the generator's command-line options take their
ranges from it, the methods' table of hyper-parameters is written from it, and the refusal tests
are generated from it.

The ranges are a **choice**, generous around the paper's values (256 symbols, a 60-sample window
at 100 Hz): up to 4096 symbols and a 4096-sample window; the rate within
`mirror_avatar.files.trials.MIN_RATE` to `MAX_RATE` (1 Hz to 10 kHz, as recordings); a pseudo-count
from 1e-12 to 1e6; 1 to 1000 k-means restarts; a seed as k-means takes it (0 to 2^32 - 1, or
None). The window must be even and the hop at most half the window (not a choice: the features
need both).
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable
from typing import Any

from mirror_avatar.common.constraints import Constraint, Either, Interval, Options, Setting, check
from mirror_avatar.files.trials import MAX_RATE, MIN_RATE

EMISSIONS = ("exemplar", "centroid")
"""What a symbol of the chain is synthesised from: one of the training frames it quantises, or
its code vector (the paper's). See `mirror_avatar.motion.generator.IMSGenerator` (``emission``)."""

MAX_WINDOW = 4096
"""The longest frame (samples)."""

CODEBOOK_SIZES = Either((Options(("auto",)), Interval(int, 2, 4096)))
"""The codebook sizes a generator takes (``n_symbols``; ``generator fit --symbols``)."""

KMEANS_SEEDS = Interval(int, 0, 2**32 - 1)
"""The seeds k-means takes (``random_state``; ``generator fit --seed``)."""

GENERATOR_SETTINGS = (
    Setting("n_symbols", "codebook size N; auto: chosen by cross-validation on the trials",
            CODEBOOK_SIZES, "auto"),
    Setting("window", "frame length (samples)",
            Interval(int, 4, MAX_WINDOW, multiple_of=2), 60),
    Setting("hop", "samples between frames, at most half the window",
            Interval(int, 1, MAX_WINDOW // 2), 15),
    Setting("rate", "sampling rate of the model; trials are resampled to it",
            Interval(float, MIN_RATE, MAX_RATE, unit="Hz"), 100.0),
    Setting("pseudo_count", "added to every transition count",
            Interval(float, 1e-12, 1e6), 1e-3),
    Setting("n_init", "k-means restarts (best distortion kept)", Interval(int, 1, 1000), 1),
    Setting("random_state", "seed of k-means and of sampling when given none",
            KMEANS_SEEDS, None, default_shown="none (unseeded)"),
    Setting("emission", "what a generated symbol is synthesised from", Options(EMISSIONS),
            "exemplar"),
)  # fmt: skip
"""Every hyper-parameter of the IMS generator, in the constructor's order; None is allowed
where it is the default (an unseeded k-means)."""

GENERATOR = {setting.key: setting for setting in GENERATOR_SETTINGS}
"""The hyper-parameters by name."""


STROKE_SETTINGS = (
    Setting("neighbours", "training strokes the next stroke is drawn from; auto: the square "
            "root of their number", Either((Options(("auto",)), Interval(int, 1, 100_000))),
            "auto"),
    Setting("jitter", "multiple of Silverman's bandwidth of the log-normal factors on a "
            "generated stroke's length and size", Interval(float, 0.0, 10.0), 0.5),
    Setting("min_reversal", "how far the position must come back from a turning point for it "
            "to count as a reversal (units)", Interval(float, 0.0, 1.0), 0.01),
    Setting("rate", "sampling rate of the model; trials are resampled to it",
            Interval(float, MIN_RATE, MAX_RATE, unit="Hz"), 100.0),
    Setting("random_state", "seed of sampling when given none", KMEANS_SEEDS, None,
            default_shown="none (unseeded)"),
)  # fmt: skip
"""Every hyper-parameter of the stroke generator (`mirror_avatar.motion.strokes`), in the
constructor's order. The ranges are a **choice**: up to 100 000 neighbours (more strokes than
hours of motion hold) and a jitter up to 10 times Silverman's bandwidth."""

STROKES = {setting.key: setting for setting in STROKE_SETTINGS}
"""The stroke generator's hyper-parameters by name."""


def check_settings(values: dict[str, Any], settings: Iterable[Setting]) -> dict[str, Any]:
    """Return ``values`` checked against ``settings``, as Python numbers.

    A key left out takes its default; None is allowed where it is the default.

    Raises
    ------
    mirror_avatar.common.constraints.ConstraintError
        A value its declaration refuses; its ``key`` names the hyper-parameter.
    """
    checked: dict[str, Any] = {}
    for setting in settings:
        unset = values.get(setting.key) is None and setting.default is None
        checked[setting.key] = None if unset else _plain(setting.read(values), setting.constraint)
    return checked


def check_hyperparameters(values: dict[str, Any]) -> dict[str, Any]:
    """Return the hyper-parameters checked against `GENERATOR_SETTINGS`, as Python numbers.

    Parameters
    ----------
    values
        Values by key; a key left out takes its default.

    Raises
    ------
    mirror_avatar.common.constraints.ConstraintError
        A value its declaration refuses, or a hop longer than half the window; its ``key``
        names the hyper-parameter.
    """
    checked = check_settings(values, GENERATOR_SETTINGS)
    check("hop", checked["hop"], Interval(int, 1, checked["window"] // 2))
    return checked


def _plain(value: Any, constraint: Constraint | None) -> Any:
    """Return an allowed value as a Python number of its interval's kind (a word stays a word)."""
    if isinstance(constraint, Interval):
        return constraint.kind(value)
    return int(value) if isinstance(value, numbers.Integral) else value
