"""The stroke generator: a person's strokes chained by nearest neighbours (METHODS section 4b).

Motion along a line is a sequence of **strokes**: the stretches between reversals, where the
position moves one way (a pause inside a stroke, or a tracking drop-out, keeps it one stroke).
Fitting cuts each training trial at its reversals (`reversals`): a turning point counts once the
position has moved back from it by more than ``min_reversal`` units (**choice**: tremor and sensor
noise turn back by less and would otherwise cut a stroke into pieces). A stroke is its length in
samples ``n``, its signed displacement ``D`` (units) and its **profile**: its positions from its
start divided by ``D``, which rise from 0 to 1 (pauses, the hold at a reversal and the small
turns back included). Every stroke is kept with the one before it in its trial.

Generation is a nearest-neighbour bootstrap of that sequence (Lall & Sharma 1996, "A nearest
neighbor bootstrap for resampling hydrologic time series"): after a stroke of ``n`` samples and
displacement ``D`` ending at position ``x``, the next stroke is one of the ``k`` training strokes
(of the opposite direction) whose predecessors' ``(log n, log |D|)`` and whose own room ahead
(the distance from their start to the edge they move towards) are nearest to the state's, in units
of each feature's SD, drawn with probability proportional to 1/rank (Lall & Sharma's kernel).
Its length and displacement are then multiplied by ``exp(h z)`` with ``z`` standard normal, ``h``
being ``jitter`` times Silverman's rule-of-thumb bandwidth of the training strokes' log lengths
(log sizes), `silverman_bandwidth` (**choice**, a smoothed bootstrap: a generated stroke is not
any training stroke, and a person whose strokes are regular gets little jitter), the
displacement capped at the room ahead, and its profile stretched to the new length. Strokes
meet at reversals, where the velocity passes through zero, so no seam adds motion the person
never made (the IMS generator's overlap-add of frames from different trials does, METHODS
section 4b). A generated trial starts at a random point of a random stroke.

The fitted model holds the training strokes, from which the training trials can be rebuilt.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import Any, Self

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.constraints import ConstraintError
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.importing import excerpt
from mirror_avatar.files.model_files import (
    check_array,
    check_object,
    load_model,
    require_arrays,
    save_model,
)
from mirror_avatar.files.trials import (
    MAX_ABS_POSITION,
    PLAYING_RANGE,
    Trial,
    compute_velocity,
)
from mirror_avatar.motion.hyperparameters import STROKES, check_settings
from mirror_avatar.motion.sampling import sample_trials

Array = NDArray[np.float64]
Seed = int | np.random.Generator | None

FORMAT_NAME = "mirror-avatar/stroke-generator"
FORMAT_VERSION = 1

MIN_STROKES = 3
"""Fewest training strokes with a predecessor that a fit needs."""

_LOG_FLOOR = 1e-4
"""Added to |D| (units) before its logarithm, so a stroke of no displacement has a feature."""


def reversals(positions: Array, min_reversal: float = 0.0) -> NDArray[np.int64]:
    """Sample indices where a trial's strokes begin and end, shape (m + 1,) for m strokes.

    The first and last samples, and each turning point: the furthest position of a stroke (the
    last sample of a hold there) once the position has come back from it by more than
    ``min_reversal`` (units). The first stroke's direction is the first move beyond
    ``min_reversal`` from the start. A signal that never moves that far is one stroke. With
    ``min_reversal`` 0, every change of the sign of the position's difference is a reversal (a
    run of equal positions keeping the sign before it).
    """
    edges = [0]
    direction, turn = 0.0, 0
    for i in range(1, positions.size):
        step = positions[i] - positions[turn]
        if direction == 0.0:
            if abs(positions[i] - positions[0]) > min_reversal:
                direction = math.copysign(1.0, positions[i] - positions[0])
                turn = i
        elif step * direction >= 0:
            turn = i
        elif -step * direction > min_reversal:
            edges.append(turn)
            direction, turn = -direction, i
    edges.append(positions.size - 1)
    return np.array(edges, dtype=np.int64)


def room_ahead(position: Array | float, direction: Array | float) -> Array:
    """Distance (units) from ``position`` to the edge of the playing range it moves towards."""
    low, high = PLAYING_RANGE
    return np.where(np.asarray(direction) > 0, high - position, position - low)


class StrokeGenerator:
    """Generate motion by chaining a person's strokes (module docstring; METHODS section 4b).

    The values each hyper-parameter allows are declared in
    `mirror_avatar.motion.hyperparameters.STROKE_SETTINGS`.

    Parameters
    ----------
    neighbours
        How many nearest training strokes the next stroke is drawn from, or ``"auto"``: the
        square root of the number of training strokes (Lall & Sharma's rule).
    jitter
        Multiple of Silverman's bandwidth (`silverman_bandwidth`) of the log-normal factors on
        each generated stroke's length and displacement.
    min_reversal
        How far (units) the position must move back from a turning point for it to count as a
        reversal (`reversals`).
    rate
        Sampling rate of the model (Hz); training trials are resampled to it.
    random_state
        Default seed of `sample` when it gets none.

    Attributes
    ----------
    lengths_ : ndarray, shape (m,)
        Each training stroke's length (samples at `rate`).
    displacements_ : ndarray, shape (m,)
        Each training stroke's signed displacement (units).
    starts_ : ndarray, shape (m,)
        Each training stroke's start position (units).
    previous_ : ndarray of int, shape (m,)
        Index of the stroke before each one in its trial, -1 for a trial's first.
    profiles_ : ndarray, shape (sum(lengths_) + m,)
        The strokes' profiles, one after another (stroke i's has ``lengths_[i] + 1`` values).
    training_summary_ : dict
        Labels, groups and durations of the training trials, the number of strokes and the seed.
    """

    lengths_: Array
    displacements_: Array
    starts_: Array
    previous_: NDArray[np.int64]
    profiles_: Array
    training_summary_: dict[str, Any]

    def __init__(
        self,
        neighbours: int | str = "auto",
        jitter: float = 0.5,
        min_reversal: float = 0.01,
        rate: float = 100.0,
        random_state: int | None = None,
    ) -> None:
        self.neighbours = neighbours
        self.jitter = jitter
        self.min_reversal = min_reversal
        self.rate = rate
        self.random_state = random_state

    # -- fitting ------------------------------------------------------------------------------

    def fit(self, trials: Sequence[Trial]) -> Self:
        """Cut the training trials into strokes (any rate; resampled to `rate`).

        Raises
        ------
        InputError
            No trials, bad hyper-parameters, or fewer than `MIN_STROKES` strokes that follow
            another in their trial.
        """
        self._check_parameters()
        if not trials:
            raise InputError("trials", "no trials to fit the generator on")
        lengths: list[float] = []
        displacements: list[float] = []
        starts: list[float] = []
        previous: list[int] = []
        profiles: list[Array] = []
        for trial in trials:
            positions = self.signal(trial)
            edges = reversals(positions, self.min_reversal)
            for number, (first, last) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
                if last == first:  # a trial of one sample
                    continue
                displacement = positions[last] - positions[first]
                profiles.append(_profile(positions[first : last + 1], displacement))
                previous.append(len(lengths) - 1 if number else -1)
                lengths.append(float(last - first))
                displacements.append(float(displacement))
                starts.append(float(positions[first]))
        self.lengths_ = np.array(lengths)
        self.displacements_ = np.array(displacements)
        self.starts_ = np.array(starts)
        self.previous_ = np.array(previous, dtype=np.int64)
        self.profiles_ = np.concatenate(profiles)
        self._prepare_sampling(source="trials")
        self.training_summary_ = {
            "labels": [t.label for t in trials],
            "groups": sorted({t.group for t in trials}),
            "durations": [round(t.duration, 6) for t in trials],
            "n_strokes": int(self.lengths_.size),
            "random_state": self.random_state,
        }
        return self

    def unfitted(self, random_state: int | None) -> StrokeGenerator:
        """Return an unfitted generator with these settings and a seed."""
        return type(self)(**self.get_params() | {"random_state": random_state})

    def signal(self, trial: Trial) -> Array:
        """Return a trial's positions at `rate` (units), resampled when needed."""
        if trial.is_uniform and math.isclose(trial.rate, self.rate, rel_tol=1e-6):
            return trial.positions
        return trial.resampled(self.rate).positions

    def _check_parameters(self) -> None:
        """Refuse hyper-parameters `STROKE_SETTINGS` refuses; keep them as Python numbers."""
        given = {key: getattr(self, key) for key in STROKES}
        for key, value in check_settings(given, STROKES.values()).items():
            setattr(self, key, value)

    def _prepare_sampling(self, source: str | os.PathLike[str]) -> None:
        """Index the strokes the chain may draw and their features (`_state`).

        A stroke may be drawn next when another precedes it in its trial and one follows it
        (the last stroke of a trial is cut short by the trial's end).
        """
        following = np.zeros(self.lengths_.size, dtype=bool)
        following[self.previous_[self.previous_ >= 0]] = True
        drawable = np.flatnonzero((self.previous_ >= 0) & following)
        if drawable.size < MIN_STROKES:
            raise InputError(
                source,
                f"{drawable.size} strokes follow another in their trial; the stroke generator "
                f"needs {MIN_STROKES}: give longer trials or more of them",
            )
        before = self.previous_[drawable]
        self._drawable = drawable
        self._directions = np.sign(self.displacements_[drawable])
        self._features = np.column_stack(
            [
                _log_length(self.lengths_[before]),
                _log_size(self.displacements_[before]),
                room_ahead(self.starts_[drawable], self._directions),
            ]
        )
        self._scale = np.maximum(self._features.std(axis=0), 1e-9)
        self._bandwidth = self.jitter * silverman_bandwidth(
            np.column_stack(
                [_log_length(self.lengths_[drawable]), _log_size(self.displacements_[drawable])]
            )
        )
        ends = np.cumsum(self.lengths_ + 1.0).astype(np.int64)
        self._profile_bounds = np.column_stack([ends - (self.lengths_ + 1).astype(np.int64), ends])
        self._k = (
            max(1, round(math.sqrt(drawable.size)))
            if self.neighbours == "auto"
            else min(int(self.neighbours), drawable.size)
        )
        weights = 1.0 / np.arange(1, self._k + 1)
        self._rank_weights = weights / weights.sum()

    def _check_fitted(self) -> None:
        if not hasattr(self, "lengths_"):
            raise InputError("generator", "not fitted: call fit(trials) or load a model first")

    # -- generation ---------------------------------------------------------------------------

    def sample_positions(self, n_samples: int, random_state: Seed = None) -> Array:
        """Generate ``n_samples`` positions at `rate` (units, within the playing range)."""
        self._check_fitted()
        if n_samples < 1:
            raise InputError("generator", f"n_samples must be positive, got {n_samples}")
        rng = np.random.default_rng(self.random_state if random_state is None else random_state)
        positions = np.empty(n_samples)
        stroke = int(self._drawable[rng.integers(self._drawable.size)])
        position = float(self.starts_[stroke])
        direction = float(np.sign(self.displacements_[stroke])) or 1.0
        time = -rng.random() * self.lengths_[stroke]
        filled = 0
        while filled < n_samples:
            length = self.lengths_[stroke] * math.exp(self._bandwidth[0] * rng.standard_normal())
            size = abs(self.displacements_[stroke]) * math.exp(
                self._bandwidth[1] * rng.standard_normal()
            )
            size = min(size, float(room_ahead(position, direction)))
            filled = self._draw_stroke(
                positions, filled, time, length, position, direction * size, stroke
            )
            position += direction * size
            time += length
            stroke = self._next_stroke(length, size, position, -direction, rng)
            direction = -direction
        low, high = PLAYING_RANGE
        return np.clip(positions, low, high)

    def _draw_stroke(
        self,
        positions: Array,
        filled: int,
        time: float,
        length: float,
        position: float,
        displacement: float,
        stroke: int,
    ) -> int:
        """Write the samples of one generated stroke into ``positions``; return how many are set.

        The stroke starts at ``time`` (samples, possibly before 0) at ``position`` and moves
        ``displacement`` over ``length`` samples along the profile of training stroke ``stroke``.
        """
        first = max(filled, math.ceil(time))
        stop = min(positions.size, math.ceil(time + length))
        if stop <= first:
            return filled
        begin, end = self._profile_bounds[stroke]
        phase = (np.arange(first, stop) - time) / length
        grid = np.linspace(0.0, 1.0, end - begin)
        profile = self.profiles_[begin:end]
        positions[first:stop] = position + displacement * np.interp(phase, grid, profile)
        return stop

    def _next_stroke(
        self,
        length: float,
        size: float,
        position: float,
        direction: float,
        rng: np.random.Generator,
    ) -> int:
        """Draw the training stroke that follows a generated one (Lall & Sharma's kernel)."""
        state = np.array(
            [_log_length(length), _log_size(size), float(room_ahead(position, direction))]
        )
        distance = np.sum(((self._features - state) / self._scale) ** 2, axis=1)
        distance[self._directions != direction] = np.inf
        k = min(self._k, int(np.isfinite(distance).sum())) or self._k
        nearest = np.argpartition(distance, k - 1)[:k]
        nearest = nearest[np.argsort(distance[nearest], kind="stable")]
        weights = self._rank_weights[:k] / self._rank_weights[:k].sum()
        return int(self._drawable[nearest[rng.choice(k, p=weights)]])

    def sample_velocity(self, n_samples: int, random_state: Seed = None) -> Array:
        """Generate a velocity signal of ``n_samples`` at `rate` (units/s), METHODS section 2."""
        return compute_velocity(self.sample_positions(n_samples, random_state), self.rate)

    def sample_velocities(self, n_samples: int, random_states: Sequence[Seed]) -> Array:
        """Generate one velocity signal of ``n_samples`` per random state, (len, n_samples)."""
        positions = np.column_stack([self.sample_positions(n_samples, s) for s in random_states])
        return compute_velocity(positions, self.rate).T.copy()

    def sample(self, duration: float, n: int = 1, random_state: Seed = None) -> list[Trial]:
        """Generate ``n`` new trials of ``duration`` seconds at `rate`.

        Labelled ``generated-1..n``, group = the training group(s), seed in the metadata; the
        same seed gives the same trials.
        """
        self._check_fitted()
        return sample_trials(
            self.sample_positions, self.rate, self.training_summary_["groups"], "strokes",
            duration, n, self.random_state if random_state is None else random_state,
        )  # fmt: skip

    # -- persistence --------------------------------------------------------------------------

    def get_params(self) -> dict[str, Any]:
        """Hyper-parameters, as given to the constructor."""
        return {
            "neighbours": self.neighbours,
            "jitter": float(self.jitter),
            "min_reversal": float(self.min_reversal),
            "rate": float(self.rate),
            "random_state": self.random_state,
        }

    def to_arrays(self) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
        """Return the fitted model's arrays and metadata, as `save` writes them.

        Arrays ``lengths``, ``displacements``, ``starts``, ``previous``, ``profiles``; metadata
        ``parameters`` and ``training``.
        """
        self._check_fitted()
        arrays: dict[str, NDArray[Any]] = {
            "lengths": self.lengths_,
            "displacements": self.displacements_,
            "starts": self.starts_,
            "previous": self.previous_,
            "profiles": self.profiles_,
        }
        return arrays, {"parameters": self.get_params(), "training": self.training_summary_}

    @classmethod
    def from_arrays(
        cls,
        arrays: Mapping[str, NDArray[Any]],
        metadata: Mapping[str, Any],
        source: str | os.PathLike[str] | None,
    ) -> StrokeGenerator:
        """Rebuild a fitted model from `to_arrays` output, checking every value it reads.

        Lengths must be whole numbers of samples from 1 to the longest session, positions and
        displacements within ±`MAX_ABS_POSITION`, each predecessor an earlier stroke or -1, and
        the profiles as many as the lengths need, finite and within ±`MAX_ABS_POSITION`.

        Raises
        ------
        InputError
            ``source: problem`` when a parameter, array or value is not as above.
        """
        parameters = check_object(source, "parameters", metadata.get("parameters"))
        unknown = sorted(parameters.keys() - STROKES.keys())
        if unknown:
            raise InputError(source, f"unknown generator parameter {excerpt(unknown[0])}")
        training = check_object(source, "training", metadata.get("training"))
        groups = training.get("groups")
        if not (isinstance(groups, list) and all(isinstance(g, str) for g in groups)):
            raise InputError(source, f"training groups {excerpt(groups)} are not a list of names")
        model = cls(**parameters)
        try:
            model._check_parameters()
        except ConstraintError as error:
            raise ConstraintError(error.key, error.value, error.constraint, source) from None
        names = ("lengths", "displacements", "starts", "previous", "profiles")
        require_arrays(source, arrays, names)
        count = len(check_array(source, "lengths", arrays["lengths"], "float", (None,)))
        bound = MAX_ABS_POSITION
        lengths = check_array(source, "lengths", arrays["lengths"], "float", (count,), 1, 1e7)
        if np.any(lengths != np.round(lengths)):
            raise InputError(source, "stroke lengths must be whole numbers of samples")
        model.lengths_ = lengths.astype(np.float64)
        model.displacements_ = check_array(
            source, "displacements", arrays["displacements"], "float", (count,), -2 * bound,
            2 * bound,
        ).astype(np.float64)  # fmt: skip
        model.starts_ = check_array(
            source, "starts", arrays["starts"], "float", (count,), -bound, bound
        ).astype(np.float64)
        previous = check_array(
            source, "previous", arrays["previous"], "integer", (count,), -1, count - 1
        ).astype(np.int64)
        if np.any(previous >= np.arange(count)):
            raise InputError(source, "each stroke's predecessor must be an earlier stroke or -1")
        model.previous_ = previous
        size = int(model.lengths_.sum()) + count
        model.profiles_ = check_array(
            source, "profiles", arrays["profiles"], "float", (size,), -bound, bound
        ).astype(np.float64)
        model.training_summary_ = training
        model._prepare_sampling(source=source if source is not None else "model")
        return model

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the fitted model to ``path`` (``.npz`` + JSON metadata), atomically."""
        save_model(path, FORMAT_NAME, FORMAT_VERSION, *self.to_arrays())

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> StrokeGenerator:
        """Read a model written by `save`.

        Raises
        ------
        InputError
            The file is missing, corrupt, truncated, of another format or inconsistent.
        """
        arrays, metadata = load_model(path, FORMAT_NAME, FORMAT_VERSION, ("lengths", "profiles"))
        return cls.from_arrays(arrays, metadata, path)


def _profile(positions: Array, displacement: float) -> Array:
    """Return a stroke's positions from its start divided by its displacement (0 to 1).

    A stroke without displacement (a signal that never moves) rises evenly.
    """
    if displacement == 0:
        return np.linspace(0.0, 1.0, positions.size)
    return (positions - positions[0]) / displacement


def silverman_bandwidth(samples: Array) -> Array:
    """Return Silverman's rule-of-thumb bandwidth of each column, ``1.06 SD m^(-1/5)``, (d,).

    ``samples`` has shape (m, d) (Silverman 1986, "Density estimation for statistics and data
    analysis", eq. 3.28).
    """
    return 1.06 * samples.std(axis=0) * samples.shape[0] ** (-0.2)


def _log_length(length: Array | float) -> Array:
    return np.log(np.asarray(length, dtype=np.float64))


def _log_size(displacement: Array | float) -> Array:
    return np.log(np.abs(np.asarray(displacement, dtype=np.float64)) + _LOG_FLOOR)
