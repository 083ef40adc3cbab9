"""A model file's arrays hold no absurd value: a deep player's weights of 1e308 are refused, naming
the file and the array, and the largest accepted weights still give finite action values."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_model_files_hostile import contents, write

from mirror_avatar.common.errors import InputError
from mirror_avatar.deep.network import count_parameters, q_values
from mirror_avatar.deep.player import MAX_LAYERS, MAX_UNITS, DeepCyberPlayer, load_deep_cyber_player
from mirror_avatar.files.model_files import MAX_MAGNITUDE


@pytest.mark.parametrize("weight", [1e308, -1e12, 2 * MAX_MAGNITUDE])
def test_absurd_deep_weights_are_refused_naming_the_file_and_the_array(tmp_path: Path, weight):
    deep = DeepCyberPlayer(hidden=(8, 4), n_slots=2)
    deep.initialise_policy(0)
    path = deep.save(tmp_path / "deep.npz")
    arrays, metadata = contents(path)
    arrays["weights"][3] = weight
    write(path, arrays, metadata)
    with pytest.raises(InputError) as error:
        load_deep_cyber_player(path)
    assert str(error.value) == (
        f"{path}: weights holds {weight!r}; its values must be finite and within -1e+09..1e+09"
    )


def test_the_largest_weights_accepted_keep_the_largest_network_finite():
    sizes = np.array([MAX_UNITS] * (MAX_LAYERS + 1) + [9], dtype=np.int64)
    weights = np.full(count_parameters(sizes), MAX_MAGNITUDE)
    values = q_values(weights, sizes, np.ones(MAX_UNITS))
    assert np.isfinite(values).all() and values.max() > 1e100
