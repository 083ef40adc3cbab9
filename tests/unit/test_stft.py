"""Tests of STFT framing and weighted overlap-add synthesis."""

import numpy as np
import pytest

from mirror_avatar.motion.stft import (
    compute_stft,
    features_to_spectra,
    hamming_window,
    resynthesise,
    spectra_to_features,
)


def test_periodic_hamming_window() -> None:
    window = hamming_window(60)
    assert window[0] == pytest.approx(0.08)
    assert window[30] == pytest.approx(1.0)
    np.testing.assert_allclose(window[1:], window[1:][::-1], atol=1e-15)


def test_unquantised_stft_resynthesises_the_signal(rng: np.random.Generator) -> None:
    signal = np.cumsum(rng.normal(size=3000)) * 1e-2
    n_covered = 15 * ((signal.size - 60) // 15) + 60
    back = resynthesise(compute_stft(signal, 60, 15), 60, 15)
    assert back.size == n_covered
    np.testing.assert_allclose(back, signal[:n_covered], rtol=0, atol=1e-10)


def test_features_round_trip_and_width(rng: np.random.Generator) -> None:
    spectra = compute_stft(rng.normal(size=600), 60, 15)
    features = spectra_to_features(spectra)
    assert features.shape == (spectra.shape[0], 60)
    np.testing.assert_allclose(features_to_spectra(features, 60), spectra, atol=1e-12)
