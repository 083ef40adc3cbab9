"""IMS generator: fitting time and sampling speed (multiples of real time), peak memory.

Fitting: 256 symbols on 30 trials of 30 s at 100 Hz, cut from the bundled real trials (each
resampled to 100 Hz and split in two halves), against the 10 s budget of the project's brief; and
the default fit, which first chooses the codebook size by leave-one-trial-out cross-validation.
Sampling: 60 s velocity references (what the virtual trainer and cyber-player training draw),
compiled chain walk and overlap-add against a straightforward baseline measured in the same run:
the symbol chain drawn with ``Generator.choice`` per frame and each frame synthesised with its own
``numpy.fft.irfft`` and added in Python.
"""

from __future__ import annotations

import time
import tracemalloc
from collections.abc import Callable

import numpy as np

from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.trials import Trial, compute_velocity, make_trial
from mirror_avatar.motion.codebook_size import SYMBOL_CANDIDATES
from mirror_avatar.motion.generator import PAPER_SYMBOLS, IMSGenerator
from mirror_avatar.motion.stft import features_to_spectra, hamming_window

FIT_BUDGET_S = 10.0
REFERENCE_S = 60.0


def training_trials(n: int = 30, seconds: float = 30.0) -> list[Trial]:
    """``n`` trials of ``seconds`` at 100 Hz, halves of the bundled real trials."""
    trials = []
    for trial in load_zhai2017():
        full = trial.resampled(100.0)
        size = int(seconds * 100)
        for start in (0, size):
            part = slice(start, start + size)
            times = full.times[part] - full.times[start]
            trials.append(make_trial(times, full.positions[part], label=trial.label))
    return trials[:n]


def baseline_velocity(model: IMSGenerator, n_samples: int, rng: np.random.Generator) -> np.ndarray:
    """Sample a velocity reference plainly: per-frame ``choice``, ``irfft`` and overlap-add."""
    window, hop = model.window, model.hop
    spectra = features_to_spectra(model.codebook_, window)
    taper = hamming_window(window)
    pad = window // hop
    n_frames = int(np.ceil(max(n_samples - window, 0) / hop)) + 1 + 2 * pad
    state = rng.choice(model.n_symbols_, p=model.startprob_)
    length = hop * (n_frames - 1) + window
    out, norm = np.zeros(length), np.zeros(length)
    for m in range(n_frames):
        if m:
            state = rng.choice(model.n_symbols_, p=model.transmat_[state])
        start = m * hop
        out[start : start + window] += np.fft.irfft(spectra[state], n=window) * taper
        norm[start : start + window] += taper**2
    signal = out / np.maximum(norm, 1e-12)
    positions = np.clip(signal[pad * hop : pad * hop + n_samples], -0.5, 0.5)
    return compute_velocity(positions, model.rate)


def measure(task: Callable[[], object]) -> tuple[float, float]:
    """Wall time (s) and peak traced memory (MB) of one call."""
    tracemalloc.start()
    start = time.perf_counter()
    task()
    elapsed = time.perf_counter() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return elapsed, peak / 2**20


def repeat(task: Callable[[], object], times: int) -> None:
    """Call ``task`` ``times`` times, keeping no result (as a training loop would)."""
    for _ in range(times):
        task()


def run(quick: bool) -> list[dict]:
    trials = training_trials()
    model = IMSGenerator(n_symbols=PAPER_SYMBOLS, random_state=0)
    fit_s, fit_mb = measure(lambda: model.fit(trials))
    chosen = IMSGenerator(random_state=0)
    auto_s, auto_mb = measure(lambda: chosen.fit(trials))

    n_samples = int(REFERENCE_S * model.rate)
    model.sample_velocity(n_samples, 0)  # compile
    n_fast, n_slow = (200, 3) if quick else (2000, 20)
    rng = np.random.default_rng(0)
    fast_s, fast_mb = measure(lambda: repeat(lambda: model.sample_velocity(n_samples, rng), n_fast))
    slow_s, slow_mb = measure(
        lambda: repeat(lambda: baseline_velocity(model, n_samples, rng), n_slow)
    )
    trial_s, trial_mb = measure(lambda: model.sample(REFERENCE_S, n=n_fast // 4, random_state=1))

    fast_rt = n_fast * REFERENCE_S / fast_s
    slow_rt = n_slow * REFERENCE_S / slow_s
    trial_rt = (n_fast // 4) * REFERENCE_S / trial_s
    return [
        {
            "name": "fit: 256 symbols, 30 trials x 30 s at 100 Hz",
            "value": fit_s,
            "unit": "s",
            "baseline": FIT_BUDGET_S,
            "ratio": fit_s / FIT_BUDGET_S,
            "peak_memory_mb": fit_mb,
            "note": f"baseline = budget; {model.training_summary_['n_frames']} frames, n_init 1",
        },
        {
            "name": "fit: codebook size chosen by cross-validation (the default)",
            "value": auto_s,
            "unit": "s",
            "peak_memory_mb": auto_mb,
            "note": f"{chosen.n_symbols_} symbols chosen of {SYMBOL_CANDIDATES}, leave one "
            "trial out; the same 30 trials",
        },
        {
            "name": "sample_velocity (60 s references)",
            "value": fast_rt,
            "unit": "x real time",
            "baseline": slow_rt,
            "ratio": fast_rt / slow_rt,
            "peak_memory_mb": fast_mb,
            "note": f"{n_fast} references; baseline: per-frame choice + irfft + overlap-add "
            f"({n_slow} references, peak {slow_mb:.1f} MB)",
        },
        {
            "name": "sample (60 s Trials, validated)",
            "value": trial_rt,
            "unit": "x real time",
            "baseline": slow_rt,
            "ratio": trial_rt / slow_rt,
            "peak_memory_mb": trial_mb,
            "note": f"{n_fast // 4} trials of positions",
        },
    ]
