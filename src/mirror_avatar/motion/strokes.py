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

The fitted model keeps the strokes the chain may draw (those with a stroke before and after them
in their trial), each with its predecessor's length and displacement: from them the training
trials can be rebuilt. `mirror_avatar.motion.sharing` writes a model of averaged strokes instead,
from which they cannot.
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

TRAINING_STROKES = "training strokes"
"""What a fitted model's strokes are (``training_summary_["holds"]``): the person's own."""

LOG_FLOOR = 1e-4
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


def _room_ahead(position: float, direction: float) -> float:
    """`room_ahead` of one position moving in one direction (+1 or -1)."""
    low, high = PLAYING_RANGE
    return high - position if direction > 0 else position - low


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
        Each stroke's length (samples at `rate`): the m strokes the chain may draw.
    displacements_ : ndarray, shape (m,)
        Each stroke's signed displacement (units).
    starts_ : ndarray, shape (m,)
        Each stroke's start position (units).
    before_lengths_ : ndarray, shape (m,)
        The length of the stroke before each one in its trial (samples).
    before_sizes_ : ndarray, shape (m,)
        The size (absolute displacement, units) of the stroke before each one.
    profiles_ : ndarray, shape (sum(lengths_) + m,)
        The strokes' profiles, one after another (stroke i's has ``lengths_[i] + 1`` values).
    bandwidth_ : ndarray, shape (2,)
        ``jitter`` times Silverman's bandwidth of the drawable training strokes' log lengths and
        log sizes: the SDs of the log-normal factors on a generated stroke's length and size.
    training_summary_ : dict
        Labels, groups and durations of the training trials, the number of strokes cut from
        them, what the strokes are (``holds``) and the seed.
    """

    lengths_: Array
    displacements_: Array
    starts_: Array
    before_lengths_: Array
    before_sizes_: Array
    profiles_: Array
    bandwidth_: Array
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
        self._keep_drawable(
            np.array(lengths), np.array(displacements), np.array(starts),
            np.array(previous, dtype=np.int64), np.concatenate(profiles), "trials",
        )  # fmt: skip
        self._prepare_sampling()
        self.training_summary_ = {
            "labels": [t.label for t in trials],
            "groups": sorted({t.group for t in trials}),
            "durations": [round(t.duration, 6) for t in trials],
            "n_strokes": len(lengths),
            "holds": TRAINING_STROKES,
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

    def _keep_drawable(
        self,
        lengths: Array,
        displacements: Array,
        starts: Array,
        previous: NDArray[np.int64],
        profiles: Array,
        source: str | os.PathLike[str],
    ) -> None:
        """Keep the strokes the chain may draw with their predecessors' lengths and sizes.

        Their jitter bandwidths (``bandwidth_``) are set from them. A stroke may be drawn when
        another precedes it in its trial (``previous`` >= 0: the index of the stroke before, -1
        for a trial's first) and one follows it (the last stroke of a trial is cut short by the
        trial's end).

        Raises
        ------
        InputError
            Fewer than `MIN_STROKES` drawable strokes.
        """
        following = np.zeros(lengths.size, dtype=bool)
        following[previous[previous >= 0]] = True
        drawable = np.flatnonzero((previous >= 0) & following)
        if drawable.size < MIN_STROKES:
            raise InputError(
                source,
                f"{drawable.size} strokes follow another in their trial; the stroke generator "
                f"needs {MIN_STROKES}: give longer trials or more of them",
            )
        ends = np.cumsum(lengths + 1.0).astype(np.int64)
        firsts = ends - (lengths + 1).astype(np.int64)
        self.lengths_ = lengths[drawable]
        self.displacements_ = displacements[drawable]
        self.starts_ = starts[drawable]
        self.before_lengths_ = lengths[previous[drawable]]
        self.before_sizes_ = np.abs(displacements[previous[drawable]])
        self.profiles_ = np.concatenate([profiles[firsts[i] : ends[i]] for i in drawable])
        self.bandwidth_ = self.jitter * silverman_bandwidth(
            np.column_stack([log_length(self.lengths_), log_size(self.displacements_)])
        )

    def _prepare_sampling(self) -> None:
        """Index the strokes' features (`_next_stroke`), profiles and rank weights."""
        self._directions = np.sign(self.displacements_)
        self._features = np.column_stack(
            [
                log_length(self.before_lengths_),
                log_size(self.before_sizes_),
                room_ahead(self.starts_, self._directions),
            ]
        )
        self._scale = np.maximum(self._features.std(axis=0), 1e-9)
        ends = np.cumsum(self.lengths_ + 1.0).astype(np.int64)
        self._profile_bounds = np.column_stack([ends - (self.lengths_ + 1).astype(np.int64), ends])
        count = self.lengths_.size
        self._k = (
            max(1, round(math.sqrt(count)))
            if self.neighbours == "auto"
            else min(int(self.neighbours), count)
        )
        weights = 1.0 / np.arange(1, self._k + 1)
        self._rank_weights = weights / weights.sum()
        self._rank_cdfs: dict[int, Array] = {}
        self._grids: dict[int, Array] = {}
        self._other_way = {d: self._directions != d for d in (-1.0, 1.0)}

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
        stroke = int(rng.integers(self.lengths_.size))
        position = float(self.starts_[stroke])
        direction = float(np.sign(self.displacements_[stroke])) or 1.0
        time = -rng.random() * self.lengths_[stroke]
        filled = 0
        while filled < n_samples:
            length = self.lengths_[stroke] * math.exp(self.bandwidth_[0] * rng.standard_normal())
            size = abs(self.displacements_[stroke]) * math.exp(
                self.bandwidth_[1] * rng.standard_normal()
            )
            size = min(size, _room_ahead(position, direction))
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
        phase = (np.arange(first, stop) - time) / length
        positions[first:stop] = position + displacement * self.profile_at(stroke, phase)
        return stop

    def profile_at(self, stroke: int, phase: NDArray[np.floating[Any]]) -> Array:
        """Return stroke ``stroke``'s profile at phases from 0 (its start) to 1 (its end).

        The profile's ``lengths_[stroke] + 1`` values are taken at evenly spaced phases and
        interpolated linearly between them.
        """
        begin, end = self._profile_bounds[stroke]
        return np.interp(phase, self._grid(end - begin), self.profiles_[begin:end])

    def _grid(self, n: int) -> Array:
        """Return ``n`` evenly spaced phases from 0 to 1 (``np.linspace``, made once per n)."""
        if n not in self._grids:
            self._grids[n] = np.linspace(0.0, 1.0, n)
        return self._grids[n]

    def _next_stroke(
        self,
        length: float,
        size: float,
        position: float,
        direction: float,
        rng: np.random.Generator,
    ) -> int:
        """Draw the training stroke that follows a generated one (Lall & Sharma's kernel)."""
        state = np.array([log_length(length), log_size(size), _room_ahead(position, direction)])
        distance = (((self._features - state) / self._scale) ** 2).sum(axis=1)
        distance[self._other_way[direction]] = np.inf
        k = min(self._k, int(np.isfinite(distance).sum())) or self._k
        nearest = np.argpartition(distance, k - 1)[:k]
        nearest = nearest[np.argsort(distance[nearest], kind="stable")]
        return int(nearest[np.searchsorted(self._rank_cdf(k), rng.random(), side="right")])

    def _rank_cdf(self, k: int) -> Array:
        """Return the cumulative rank weights of ``k`` neighbours, ending at 1.

        Searched with one uniform draw, they pick a rank as ``rng.choice(k, p=weights)`` does
        with the same generator (the same draw and the same index), without its checks.
        """
        if k not in self._rank_cdfs:
            cdf = np.cumsum(self._rank_weights[:k] / self._rank_weights[:k].sum())
            self._rank_cdfs[k] = cdf / cdf[-1]
        return self._rank_cdfs[k]

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

        Arrays ``lengths``, ``displacements``, ``starts``, ``before_lengths``,
        ``before_sizes``, ``profiles``, ``bandwidth``; metadata ``parameters`` and ``training``.
        """
        self._check_fitted()
        arrays: dict[str, NDArray[Any]] = {
            "lengths": self.lengths_,
            "displacements": self.displacements_,
            "starts": self.starts_,
            "before_lengths": self.before_lengths_,
            "before_sizes": self.before_sizes_,
            "profiles": self.profiles_,
            "bandwidth": self.bandwidth_,
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
        displacements within ±`MAX_ABS_POSITION`, the profiles as many as the lengths need,
        finite and within ±`MAX_ABS_POSITION`, and at least `MIN_STROKES` strokes. Arrays
        written before the predecessors' features were kept (each stroke's ``previous``
        stroke instead, every training stroke, no ``bandwidth``) are read as the fit would
        have kept them.

        Raises
        ------
        InputError
            ``source: problem`` when a parameter, array or value is not as above.
        """
        where = source if source is not None else "model"
        model = cls(**_parameters(metadata, where))
        training = check_object(source, "training", metadata.get("training"))
        groups = training.get("groups")
        if not (isinstance(groups, list) and all(isinstance(g, str) for g in groups)):
            raise InputError(source, f"training groups {excerpt(groups)} are not a list of names")
        legacy = "previous" in arrays
        names = ("lengths", "displacements", "starts", "profiles") + (
            ("previous",) if legacy else ("before_lengths", "before_sizes", "bandwidth")
        )
        require_arrays(source, arrays, names)
        checked = _checked_strokes(arrays, source)
        if legacy:
            model._read_previous(checked, arrays["previous"], where)
        else:
            model._read_drawable(checked, arrays, where)
        model.training_summary_ = training
        model._prepare_sampling()
        return model

    def _read_previous(
        self, strokes: dict[str, Array], previous: NDArray[Any], source: str | os.PathLike[str]
    ) -> None:
        """Keep the drawable strokes of arrays that link each stroke to the one before it."""
        count = strokes["lengths"].size
        previous = check_array(
            source, "previous", previous, "integer", (count,), -1, count - 1
        ).astype(np.int64)
        if np.any(previous >= np.arange(count)):
            raise InputError(source, "each stroke's predecessor must be an earlier stroke or -1")
        self._keep_drawable(
            strokes["lengths"], strokes["displacements"], strokes["starts"], previous,
            strokes["profiles"], source,
        )  # fmt: skip

    def _read_drawable(
        self,
        strokes: dict[str, Array],
        arrays: Mapping[str, NDArray[Any]],
        source: str | os.PathLike[str],
    ) -> None:
        """Take the drawable strokes and their predecessors' features as the arrays hold them."""
        count = strokes["lengths"].size
        if count < MIN_STROKES:
            raise InputError(source, f"{count} strokes; the stroke generator needs {MIN_STROKES}")
        bound = MAX_ABS_POSITION
        self.lengths_ = strokes["lengths"]
        self.displacements_ = strokes["displacements"]
        self.starts_ = strokes["starts"]
        self.profiles_ = strokes["profiles"]
        self.before_lengths_ = check_array(
            source, "before_lengths", arrays["before_lengths"], "float", (count,), 1, 1e7
        ).astype(np.float64)
        self.before_sizes_ = check_array(
            source, "before_sizes", arrays["before_sizes"], "float", (count,), 0, 2 * bound
        ).astype(np.float64)
        self.bandwidth_ = check_array(
            source, "bandwidth", arrays["bandwidth"], "float", (2,), 0, 10
        ).astype(np.float64)

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


def _parameters(metadata: Mapping[str, Any], source: str | os.PathLike[str]) -> dict[str, Any]:
    """Return a model file's hyper-parameters, refusing what `STROKE_SETTINGS` refuses."""
    parameters = check_object(source, "parameters", metadata.get("parameters"))
    unknown = sorted(parameters.keys() - STROKES.keys())
    if unknown:
        raise InputError(source, f"unknown generator parameter {excerpt(unknown[0])}")
    try:
        return check_settings(dict(parameters), STROKES.values())
    except ConstraintError as error:
        raise ConstraintError(error.key, error.value, error.constraint, source) from None


def _checked_strokes(
    arrays: Mapping[str, NDArray[Any]], source: str | os.PathLike[str] | None
) -> dict[str, Array]:
    """Return a model file's stroke lengths, displacements, starts and profiles, checked.

    Raises
    ------
    InputError
        A length that is not a whole number from 1 to 1e7 samples, a position, displacement or
        profile value beyond ±`MAX_ABS_POSITION` (displacements ±2x), or profiles of a size
        the lengths do not need.
    """
    count = len(check_array(source, "lengths", arrays["lengths"], "float", (None,)))
    bound = MAX_ABS_POSITION
    lengths = check_array(source, "lengths", arrays["lengths"], "float", (count,), 1, 1e7)
    if np.any(lengths != np.round(lengths)):
        raise InputError(source, "stroke lengths must be whole numbers of samples")
    displacements = check_array(
        source, "displacements", arrays["displacements"], "float", (count,), -2 * bound, 2 * bound
    )
    starts = check_array(source, "starts", arrays["starts"], "float", (count,), -bound, bound)
    size = int(lengths.sum()) + count
    profiles = check_array(source, "profiles", arrays["profiles"], "float", (size,), -bound, bound)
    return {
        "lengths": lengths.astype(np.float64),
        "displacements": displacements.astype(np.float64),
        "starts": starts.astype(np.float64),
        "profiles": profiles.astype(np.float64),
    }


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


def log_length(length: Array | float) -> Array:
    """Return the logarithm of stroke lengths (samples): the chain's first feature."""
    return np.log(np.asarray(length, dtype=np.float64))


def log_size(displacement: Array | float) -> Array:
    """Return ``log(|D| + LOG_FLOOR)`` of displacements (units): the chain's second feature."""
    return np.log(np.abs(np.asarray(displacement, dtype=np.float64)) + LOG_FLOOR)
