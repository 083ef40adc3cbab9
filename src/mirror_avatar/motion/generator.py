"""The IMS generator: a Markov chain over vector-quantised STFT frames (METHODS section 4).

Learns a person's individual motor signature from a few solo trials and generates new motion with
it. Follows METHODS section 4:

1. frames of the 100 Hz position signal: periodic Hamming window of ``window`` = 60 samples, hop
   15 (overlap 45), FFT length 60 -> 31 one-sided bins;
2. features: ``[Re X0..Re X30, Im X1..Im X29]`` (60 numbers per frame, phase kept);
3. codebook: Lloyd's algorithm (scikit-learn `KMeans`, ``algorithm="lloyd"``) with ``n_symbols``
   code vectors; each frame's symbol is its nearest code vector;
4. a first-order Markov chain over the symbols: transitions counted over all training trials
   (maximum likelihood), plus ``pseudo_count`` in every cell (**choice**, default 1e-3: a row
   seen ~10 times keeps ~97 % of its counted mass) so every row, including a symbol never
   followed by another in training, is a valid distribution; larger pseudo-counts make random
   jumps that add fast strokes to slow motion, so the default stays small. The initial symbol is
   drawn from the symbols' frequencies in training (**choice**: too few trials to estimate a
   start distribution). Baum-Welch on a hidden chain (METHODS: an option) is not implemented.
5. synthesis: a sampled symbol sequence; each symbol stands for one of the training frames it
   quantises (``emission="exemplar"``, the default: the frame that followed the previous one
   in its trial when that frame has this symbol, else one of the symbol's frames drawn evenly)
   or for its code vector (``emission="centroid"``, the paper); the frames inverse-transformed,
   weighted overlap-add with the same window; positions clipped to [-0.5, 0.5], velocity as
   METHODS section 2. Frames are generated beyond both ends and trimmed, so the window's taper
   never shows ("no edge artefacts").

Each frame's windowed time-domain form is precomputed after fitting, so generation is a
compiled chain walk, a compiled choice of frames and a compiled overlap-add.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import Any, Self

import numpy as np
from numba import njit
from numpy.typing import NDArray
from sklearn.cluster import KMeans

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
from mirror_avatar.motion.codebook_size import MIN_FRAMES_PER_SYMBOL, choose_n_symbols
from mirror_avatar.motion.hyperparameters import GENERATOR, check_hyperparameters
from mirror_avatar.motion.markov import (
    count_transitions,
    emit_exemplars,
    estimate_transitions,
    group_members,
    sample_chain,
)
from mirror_avatar.motion.sampling import sample_trials
from mirror_avatar.motion.stft import (
    compute_stft,
    features_to_spectra,
    hamming_window,
    overlap_add_into,
    overlap_norm,
    spectra_to_features,
    synthesis_frames,
)

PAPER_SYMBOLS = 256
"""The paper's codebook size (after a sweep over 32-256 on 30 trials per person)."""

PAPER_EMISSION = "centroid"
"""The paper's synthesis: each symbol's code vector."""

SIDE_BY_SIDE = 8
"""Velocity signals `IMSGenerator.sample_velocities` filters together (**choice**: enough to
overlap the filter's recursions; 8 references of a minute stay within the processor's cache)."""

FORMAT_NAME = "mirror-avatar/ims-generator"
FORMAT_VERSION = 1
"""Files without ``emission`` in their parameters were written before it existed: centroid."""
Array = NDArray[np.float64]
Seed = int | np.random.Generator | None


_NO_FRAMES = np.empty(0, dtype=np.int64)
"""The exemplar arguments of `synthesise_columns` under centroid emission (unread)."""


@njit(cache=True, nogil=True)
def synthesise_columns(
    cumulative: Array,
    start_cumulative: Array,
    uniforms: Array,
    starts: NDArray[np.int64],
    members: NDArray[np.int64],
    following: NDArray[np.int64],
    frame_symbols: NDArray[np.int64],
    frames: Array,
    hop: int,
    norm: Array,
    start: int,
    low: float,
    high: float,
    positions: Array,
) -> None:
    """Synthesise one position signal per column of ``positions`` (n, L) from its uniforms.

    Column j walks the chain on ``uniforms[j, 0]`` (`sample_chain`), picks its frames with
    ``uniforms[j, 1]`` under exemplar emission (`emit_exemplars`, when ``uniforms`` has two
    rows per column; ``starts`` to ``frame_symbols`` are then its arguments) or takes the
    symbols' code vectors, and overlap-adds them (`overlap_add_into`, ``frames`` to ``high``
    its arguments). One call for a group of signals: each column is what it is alone.
    """
    for j in range(uniforms.shape[0]):
        sequence = sample_chain(cumulative, start_cumulative, uniforms[j, 0])
        if uniforms.shape[1] > 1:
            sequence = emit_exemplars(
                sequence, uniforms[j, 1], starts, members, following, frame_symbols
            )
        overlap_add_into(frames, sequence, hop, norm, start, low, high, positions[:, j])


class IMSGenerator:
    """Generate motion with a person's individual motor signature.

    The values each hyper-parameter allows are declared in
    `mirror_avatar.motion.hyperparameters.GENERATOR_SETTINGS` (METHODS section 4 tables them).

    Parameters
    ----------
    n_symbols
        Codebook size N, or ``"auto"``: chosen from the training trials by `choose_n_symbols`
        (cross-validation; the choice and its evidence go into ``training_summary_``). The
        paper used 256 (`PAPER_SYMBOLS`) with 30 trials per person; on a few trials that many
        symbols make the chain replay its training frames, and "auto" is the default
        (**departure**: METHODS section 4 fixes N after a sweep).
    window
        Frame length in samples (even; paper: 60 at 100 Hz).
    hop
        Samples between frames (paper: 15, overlap 45).
    rate
        Sampling rate of the model (Hz); training trials are resampled to it.
    emission
        ``"exemplar"`` (default): each generated symbol is one of the training frames it
        quantises, continuing the previous frame's trial when the chain follows it;
        ``"centroid"``: its code vector, as the paper. A code vector averages its frames and
        shrinks their amplitude, so centroid motion is slower and smoother than the person's
        (METHODS section 4, "Fidelity"); exemplar frames keep it. The fitted model then holds
        the training frames, from which the training trials can be rebuilt.
    pseudo_count
        Added to every transition count (**choice**).
    n_init
        k-means restarts (best distortion kept).
    random_state
        Seed of k-means (and default seed of `sample` when it gets none).

    Attributes
    ----------
    codebook_ : ndarray, shape (n_symbols, window)
        Code vectors (feature space of `mirror_avatar.motion.stft.spectra_to_features`).
    transmat_ : ndarray, shape (n_symbols, n_symbols)
        Transition probabilities, rows sum to 1.
    startprob_ : ndarray, shape (n_symbols,)
        Initial-symbol probabilities.
    exemplars_ : ndarray, shape (n_frames, window)
        The training frames' features (exemplar emission only; empty for centroid).
    exemplar_next_ : ndarray of int, shape (n_frames,)
        Index of the frame that followed each one in its trial, -1 at a trial's end.
    n_symbols_ : int
        The codebook size fitted (``n_symbols``, or the size "auto" chose).
    training_summary_ : dict
        Labels, groups and durations of the training trials, frames, distortion, seed, and how
        the codebook size was chosen (``complexity``).
    """

    codebook_: Array
    transmat_: Array
    startprob_: Array
    exemplars_: Array
    exemplar_next_: NDArray[np.int64]
    n_symbols_: int
    training_summary_: dict[str, Any]

    def __init__(
        self,
        n_symbols: int | str = "auto",
        window: int = 60,
        hop: int = 15,
        rate: float = 100.0,
        pseudo_count: float = 1e-3,
        n_init: int = 1,
        random_state: int | None = None,
        emission: str = "exemplar",
    ) -> None:
        self.n_symbols = n_symbols
        self.window = window
        self.hop = hop
        self.rate = rate
        self.emission = emission
        self.pseudo_count = pseudo_count
        self.n_init = n_init
        self.random_state = random_state

    # -- fitting ------------------------------------------------------------------------------

    def fit(self, trials: Sequence[Trial]) -> Self:
        """Learn the codebook and the chain from solo trials (any rate; resampled to `rate`).

        Raises
        ------
        InputError
            No trials, bad hyper-parameters, or fewer than `MIN_FRAMES_PER_SYMBOL` frames per
            symbol.
        """
        self._check_parameters()
        signals = [self.signal(trial) for trial in trials]
        if not signals:
            raise InputError("trials", "no trials to fit the generator on")
        if self.n_symbols == "auto":
            complexity = choose_n_symbols(trials, self.with_symbols)
        else:
            complexity = {"rule": "fixed", "chosen": self.n_symbols}
        self.n_symbols_ = int(complexity["chosen"])
        features = [self._features(signal) for signal in signals]
        n_frames = sum(f.shape[0] for f in features)
        if n_frames < MIN_FRAMES_PER_SYMBOL * self.n_symbols_:
            most = max(n_frames // MIN_FRAMES_PER_SYMBOL, 1)
            raise InputError(
                "trials",
                f"{n_frames} frames are too few for {self.n_symbols_} symbols (a codebook needs "
                f"{MIN_FRAMES_PER_SYMBOL} frames per symbol): give --symbols {most} or fewer, "
                "--symbols auto, or more trials",
            )
        kmeans = KMeans(
            n_clusters=self.n_symbols_,
            n_init=self.n_init,
            algorithm="lloyd",
            random_state=self.random_state,
        ).fit(np.vstack(features))
        self.codebook_ = kmeans.cluster_centers_.astype(np.float64)
        sequences = [self._quantise(f) for f in features]
        self.transmat_ = estimate_transitions(
            count_transitions(sequences, self.n_symbols_), self.pseudo_count
        )
        frequency = np.bincount(np.concatenate(sequences), minlength=self.n_symbols_) + 0.0
        self.startprob_ = frequency / frequency.sum()
        self._keep_exemplars(features)
        self.training_summary_ = {
            "labels": [t.label for t in trials],
            "groups": sorted({t.group for t in trials}),
            "durations": [round(t.duration, 6) for t in trials],
            "n_frames": int(n_frames),
            "distortion": float(kmeans.inertia_ / (n_frames * self.window)),
            "symbols_used": float(np.mean(frequency > 0)),
            "random_state": self.random_state,
            "complexity": complexity,
        }
        self._prepare_sampling()
        return self

    def unfitted(self, random_state: int | None) -> IMSGenerator:
        """Return an unfitted generator with these settings, the codebook size fitted and a seed."""
        return type(self)(
            **self.get_params() | {"n_symbols": self.n_symbols_, "random_state": random_state}
        )

    def with_symbols(self, n_symbols: int) -> IMSGenerator:
        """Return an unfitted generator with these settings and a codebook of ``n_symbols``."""
        return type(self)(**self.get_params() | {"n_symbols": n_symbols})

    def _keep_exemplars(self, features: list[Array]) -> None:
        """Keep the training frames and each one's successor in its trial (exemplar emission)."""
        if self.emission == "centroid":
            self.exemplars_ = np.empty((0, self.window))
            self.exemplar_next_ = np.empty(0, dtype=np.int64)
            return
        self.exemplars_ = np.vstack(features)
        following = []
        for start, count in zip(
            np.cumsum([0] + [len(f) for f in features[:-1]]), map(len, features), strict=True
        ):
            successor = np.arange(start + 1, start + count + 1, dtype=np.int64)
            successor[-1:] = -1
            following.append(successor)
        self.exemplar_next_ = np.concatenate(following)

    def _check_parameters(self) -> None:
        """Refuse hyper-parameters their declarations refuse; keep them as Python numbers.

        Raises
        ------
        mirror_avatar.common.constraints.ConstraintError
            Naming the hyper-parameter (`mirror_avatar.motion.hyperparameters.GENERATOR_SETTINGS`).
        """
        given = {key: getattr(self, key) for key in GENERATOR}
        for key, value in check_hyperparameters(given).items():
            setattr(self, key, value)

    def signal(self, trial: Trial) -> Array:
        """Return a trial's positions at `rate` (units), resampled when needed."""
        if trial.is_uniform and math.isclose(trial.rate, self.rate, rel_tol=1e-6):
            return trial.positions
        return trial.resampled(self.rate).positions

    def frame_features(self, trial: Trial) -> Array:
        """Return the feature vectors of a trial's STFT frames, shape (frames, window)."""
        return self._features(self.signal(trial))

    def _features(self, signal: Array) -> Array:
        return spectra_to_features(compute_stft(signal, self.window, self.hop))

    def _quantise(self, features: Array) -> NDArray[np.int64]:
        distances = (
            np.sum(features**2, axis=1)[:, None]
            - 2.0 * features @ self.codebook_.T
            + np.sum(self.codebook_**2, axis=1)[None, :]
        )
        return np.argmin(distances, axis=1).astype(np.int64)

    def _prepare_sampling(self) -> None:
        """Precompute the synthesis frames and the chain's cumulative probabilities.

        Exemplar emission: the training frames, then the code vectors, which stand for a
        symbol no training frame is nearest to (possible only in a file edited by hand).
        """
        frames = self.codebook_
        if self.emission == "exemplar":
            frames = np.vstack([self.exemplars_, self.codebook_])
            symbols = self._quantise(self.exemplars_)
            self._members = group_members(symbols, self.n_symbols_, len(self.exemplars_))
            self._exemplar_symbols = symbols
        self._frames = synthesis_frames(features_to_spectra(frames, self.window), self.window)
        self._window_squared = hamming_window(self.window) ** 2
        self._norms: dict[int, Array] = {}
        self._cumulative = np.cumsum(self.transmat_, axis=1)
        self._cumulative[:, -1] = 1.0
        self._start_cumulative = np.cumsum(self.startprob_)
        self._start_cumulative[-1] = 1.0

    def _check_fitted(self) -> None:
        if not hasattr(self, "codebook_"):
            raise InputError("generator", "not fitted: call fit(trials) or load a model first")

    # -- diagnostics --------------------------------------------------------------------------

    def score(self, trials: Sequence[Trial]) -> dict[str, float]:
        """Diagnostics of the model on trials.

        Returns
        -------
        dict
            ``distortion`` (mean squared quantisation error per feature), ``symbols_used``
            (fraction of code vectors that are some frame's nearest) and
            ``log_likelihood`` (mean log-probability per transition of the trials' symbols).
        """
        self._check_fitted()
        features = [self.frame_features(t) for t in trials]
        sequences = [self._quantise(f) for f in features]
        stacked, symbols = np.vstack(features), np.concatenate(sequences)
        error = np.sum((stacked - self.codebook_[symbols]) ** 2) / stacked.size
        log_p = [np.log(self.transmat_[s[:-1], s[1:]]) for s in sequences if s.size > 1]
        return {
            "distortion": float(error),
            "symbols_used": float(np.unique(symbols).size / self.n_symbols_),
            "log_likelihood": float(np.mean(np.concatenate(log_p))) if log_p else math.nan,
        }

    # -- generation ---------------------------------------------------------------------------

    def sample_positions(self, n_samples: int, random_state: Seed = None) -> Array:
        """Generate ``n_samples`` positions at `rate` (units, clipped to [-0.5, 0.5])."""
        self._check_sampling(n_samples)
        positions = np.empty((n_samples, 1))
        self._sample_positions_into(positions, [random_state])
        return positions[:, 0]

    def _check_sampling(self, n_samples: int) -> None:
        self._check_fitted()
        if n_samples < 1:
            raise InputError("generator", f"n_samples must be positive, got {n_samples}")

    def _sample_positions_into(self, positions: Array, random_states: Sequence[Seed]) -> None:
        """`sample_positions` from each random state, written into the columns of ``positions``.

        Column j, shape (n,), draws only from ``random_states[j]``: each generator's uniforms
        are drawn first (the chain's, then the emission's), and every column is then
        synthesised in one compiled call (`synthesise_columns`).
        """
        n_samples = positions.shape[0]
        pad = self.window // self.hop
        n_frames = math.ceil(max(n_samples - self.window, 0) / self.hop) + 1 + 2 * pad
        exemplar = self.emission == "exemplar"
        uniforms = np.empty((len(random_states), 2 if exemplar else 1, n_frames))
        for column, random_state in enumerate(random_states):
            rng = np.random.default_rng(self.random_state if random_state is None else random_state)
            for row in uniforms[column]:
                rng.random(out=row)
        norm = self._norms.get(n_frames)
        if norm is None:
            norm = self._norms[n_frames] = overlap_norm(n_frames, self.hop, self._window_squared)
        starts, members = self._members if exemplar else (_NO_FRAMES, _NO_FRAMES)
        low, high = PLAYING_RANGE
        synthesise_columns(
            self._cumulative, self._start_cumulative, uniforms, starts, members,
            self.exemplar_next_ if exemplar else _NO_FRAMES,
            self._exemplar_symbols if exemplar else _NO_FRAMES, self._frames, self.hop, norm,
            pad * self.hop, low, high, positions,
        )  # fmt: skip

    def sample_velocity(self, n_samples: int, random_state: Seed = None) -> Array:
        """Generate a velocity signal of ``n_samples`` at `rate` (units/s).

        The velocity of `sample_positions` (METHODS section 2,
        `mirror_avatar.files.trials.compute_velocity`); this is what a virtual trainer uses as its
        reference r_s.
        """
        return self.sample_velocities(n_samples, [random_state])[0]

    def sample_velocities(self, n_samples: int, random_states: Sequence[Seed]) -> Array:
        """Generate one velocity signal of ``n_samples`` per random state (units/s).

        Row j is ``sample_velocity(n_samples, random_states[j])``. The signals are filtered
        `SIDE_BY_SIDE` at a time (`mirror_avatar.files.trials.compute_velocity` of their columns),
        so the filter's recursions overlap while a group's signals stay in the processor's cache.

        Returns
        -------
        numpy.ndarray
            Shape (len(random_states), n_samples).
        """
        self._check_sampling(n_samples)
        velocities = np.empty((len(random_states), n_samples))
        for first in range(0, len(random_states), SIDE_BY_SIDE):
            group = random_states[first : first + SIDE_BY_SIDE]
            positions = np.empty((n_samples, len(group)))
            self._sample_positions_into(positions, group)
            velocities[first : first + len(group)] = compute_velocity(positions, self.rate).T
        return velocities

    def sample(self, duration: float, n: int = 1, random_state: Seed = None) -> list[Trial]:
        """Generate ``n`` new trials of ``duration`` seconds at `rate`.

        Parameters
        ----------
        duration
            Length of each trial (s).
        n
            Number of trials.
        random_state
            Seed or generator; the same seed gives the same trials. None uses the
            constructor's ``random_state``.

        Returns
        -------
        list of Trial
            Labelled ``generated-1..n``, group = the training group(s), seed in the metadata.
        """
        return sample_trials(
            self.sample_positions, self.rate, self.training_summary_["groups"],
            "ims-markov-chain", duration, n,
            self.random_state if random_state is None else random_state,
        )  # fmt: skip

    # -- persistence --------------------------------------------------------------------------

    def get_params(self) -> dict[str, Any]:
        """Hyper-parameters, as given to the constructor."""
        return {
            "n_symbols": self.n_symbols if self.n_symbols == "auto" else int(self.n_symbols),
            "window": int(self.window),
            "hop": int(self.hop),
            "rate": float(self.rate),
            "pseudo_count": float(self.pseudo_count),
            "n_init": int(self.n_init),
            "random_state": self.random_state,
            "emission": self.emission,
        }

    def to_arrays(self) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
        """Return the fitted model's arrays and metadata, as `save` writes them.

        Arrays ``codebook``, ``transmat``, ``startprob``, and for exemplar emission
        ``exemplars`` and ``exemplar_next``; metadata ``parameters`` (with the
        codebook size fitted: a model fitted with "auto" is saved with the size it chose, the
        choice recorded in ``training``), ``training``.
        """
        self._check_fitted()
        arrays: dict[str, NDArray[Any]] = {
            "codebook": self.codebook_,
            "transmat": self.transmat_,
            "startprob": self.startprob_,
        }
        if self.emission == "exemplar":
            arrays |= {"exemplars": self.exemplars_, "exemplar_next": self.exemplar_next_}
        parameters = self.get_params() | {"n_symbols": self.n_symbols_}
        return arrays, {"parameters": parameters, "training": self.training_summary_}

    @classmethod
    def from_arrays(
        cls,
        arrays: Mapping[str, NDArray[Any]],
        metadata: Mapping[str, Any],
        source: str | os.PathLike[str] | None,
    ) -> IMSGenerator:
        """Rebuild a fitted model from `to_arrays` output, checking every value it reads.

        The parameters must be as `mirror_avatar.motion.hyperparameters.GENERATOR_SETTINGS`
        declares them (a refused one raises a `ConstraintError` naming ``source`` and the
        parameter); the training summary must name its groups; the code vectors must be finite
        floats within ±``MAX_ABS_POSITION * window`` (the largest feature of a frame of
        positions within
        `mirror_avatar.files.trials.MAX_ABS_POSITION`), and so must the exemplars; each exemplar's
        successor must be another exemplar or -1; the transition and initial probabilities
        must be distributions. Parameters without ``emission`` (files written before it)
        mean centroid emission.

        Raises
        ------
        InputError
            ``source: problem`` when the parameters are invalid or an array is missing, of the
            wrong dtype or shape, non-finite, too large or not a probability distribution.
        """
        parameters = check_object(source, "parameters", metadata.get("parameters"))
        unknown = sorted(parameters.keys() - GENERATOR.keys())
        if unknown:
            raise InputError(source, f"unknown generator parameter {excerpt(unknown[0])}")
        training = check_object(source, "training", metadata.get("training"))
        groups = training.get("groups")
        if not (isinstance(groups, list) and all(isinstance(g, str) for g in groups)):
            raise InputError(source, f"training groups {excerpt(groups)} are not a list of names")
        model = cls(**{"emission": "centroid"} | parameters)
        try:
            model._check_parameters()
        except ConstraintError as error:
            raise ConstraintError(error.key, error.value, error.constraint, source) from None
        if model.n_symbols == "auto":
            raise InputError(source, "a fitted model must name its codebook size, not auto")
        model.n_symbols_ = int(model.n_symbols)
        model.training_summary_ = training
        require_arrays(source, arrays, ("codebook", "transmat", "startprob"))
        n, width = model.n_symbols_, model.window
        bound = MAX_ABS_POSITION * width
        codebook = check_array(
            source, "codebook", arrays["codebook"], "float", (n, width), -bound, bound
        )
        transmat = check_array(source, "transmat", arrays["transmat"], "float", (n, n))
        startprob = check_array(source, "startprob", arrays["startprob"], "float", (n,))
        rows = np.concatenate([transmat.sum(axis=1), [startprob.sum()]])
        if np.any(transmat < 0) or np.any(startprob < 0) or not np.allclose(rows, 1.0, atol=1e-9):
            raise InputError(source, "transition probabilities are not valid distributions")
        model.codebook_ = codebook.astype(np.float64)
        model.transmat_ = transmat.astype(np.float64)
        model.startprob_ = startprob.astype(np.float64)
        if model.emission == "exemplar":
            require_arrays(source, arrays, ("exemplars", "exemplar_next"))
            following = check_array(
                source, "exemplar_next", arrays["exemplar_next"], "integer", (None,)
            )
            count = len(following)
            following = check_array(
                source, "exemplar_next", following, "integer", (count,), -1, count - 1
            )
            exemplars = check_array(
                source, "exemplars", arrays["exemplars"], "float", (count, width), -bound, bound
            )
            model.exemplars_ = exemplars.astype(np.float64)
            model.exemplar_next_ = following.astype(np.int64)
        model._prepare_sampling()
        return model

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the fitted model to ``path`` (``.npz`` + JSON metadata), atomically."""
        save_model(path, FORMAT_NAME, FORMAT_VERSION, *self.to_arrays())

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> IMSGenerator:
        """Read a model written by `save`.

        Raises
        ------
        InputError
            The file is missing, corrupt, truncated, of another format or inconsistent.
        """
        arrays, metadata = load_model(
            path, FORMAT_NAME, FORMAT_VERSION, ("codebook", "transmat", "startprob")
        )
        return cls.from_arrays(arrays, metadata, path)
