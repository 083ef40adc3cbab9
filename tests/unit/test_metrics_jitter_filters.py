"""The jitter module's zero-phase filters are `scipy.signal.sosfiltfilt`'s, one series or many;
a player's jitter from one band-pass is the index and value computed each on its own."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from mirror_avatar.common.errors import InputError
from mirror_avatar.metrics.jitter import (
    JITTER_BAND,
    band_pass,
    jitter_index,
    jitter_value,
    player_jitter,
    shortest_series,
    smooth_part,
)

RATE = 33.3


@pytest.mark.parametrize("shape", [(668,), (19, 668), (3, 4, 200), (shortest_series(),)])
def test_the_filters_are_scipys(rng, shape):
    v = rng.normal(size=shape)
    designs = {
        band_pass: signal.butter(4, JITTER_BAND, btype="bandpass", fs=RATE, output="sos"),
        smooth_part: signal.butter(4, JITTER_BAND[0], fs=RATE, output="sos"),
    }
    for function, sos in designs.items():
        np.testing.assert_allclose(
            function(v, RATE), signal.sosfiltfilt(sos, v), rtol=0, atol=1e-12
        )


def test_a_series_no_longer_than_the_padding_is_refused(rng):
    with pytest.raises(InputError, match="too few for the filter"):
        band_pass(rng.normal(size=shortest_series() - 1), RATE)


def test_a_players_jitter_is_its_index_and_value_by_scipy(rng):
    v = rng.normal(size=668)
    b = signal.sosfiltfilt(
        signal.butter(4, JITTER_BAND, btype="bandpass", fs=RATE, output="sos"), v
    )
    rms = np.sqrt(np.mean(v**2))
    index, value = player_jitter(v, RATE)
    np.testing.assert_allclose(index, np.abs(signal.hilbert(b)) / (np.sqrt(2) * rms), atol=1e-12)
    assert value == pytest.approx(np.sqrt(np.mean(b**2)) / rms, rel=1e-12)
    np.testing.assert_array_equal(index, jitter_index(v, RATE))
    assert value == jitter_value(v, RATE)
