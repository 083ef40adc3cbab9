"""Several players' columns in one trial file (``--columns``), and resampling on reading."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.interpolate import PchipInterpolator

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.importing import ColumnMap, ImportOptions, parse_columns
from mirror_avatar.files.trial_files import read_trial, read_trial_file


def jittered(n: int = 200, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (s) at an irregular ~13 Hz and two players' positions (units) at them."""
    rng = np.random.default_rng(seed)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.055, 0.1, n - 1))])
    return t, 0.3 * np.sin(2.4 * t), 0.2 * np.cos(1.7 * t)


def test_a_column_map_is_read_in_order() -> None:
    mapping = parse_columns(" time = t , human=h,avatar = a")
    assert mapping == ColumnMap("t", (("human", "h"), ("avatar", "a")))
    assert mapping.labels == ("human", "avatar") and mapping.columns == ("h", "a")
    assert str(mapping) == "time=t,human=h,avatar=a"


@pytest.mark.parametrize("text", ["time=t,.hidden=h", "time=t,a/b=h", "time=t,a=h,b=h"])
def test_labels_that_cannot_name_files_and_repeated_columns_are_refused(text) -> None:
    with pytest.raises(InputError, match="--columns"):
        parse_columns(text)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_each_player_is_a_trial_resampled_by_pchip(tmp_path, suffix) -> None:
    t, h, a = jittered()
    path = tmp_path / f"trial{suffix}"
    frame = pd.DataFrame({"stamp_ms": t * 1000, "h": h, "a": a})
    frame.to_csv(path, index=False) if suffix == ".csv" else frame.to_parquet(path)
    options = ImportOptions(time_unit="ms", columns=parse_columns("time=stamp_ms,human=h,avatar=a"),
                            resample=50.0)  # fmt: skip
    human, avatar = read_trial_file(path, options)
    assert (human.label, avatar.label) == ("trial-human", "trial-avatar")
    assert human.metadata["player"] == "human" and avatar.metadata["source"] == str(path)
    assert human.metadata["resampled_from"] == pytest.approx((t.size - 1) / t[-1])
    grid = np.arange(human.n_samples) / 50.0
    assert human.is_uniform and grid[-1] <= t[-1] < grid[-1] + 1 / 50
    np.testing.assert_allclose(human.positions, PchipInterpolator(t, h)(grid), atol=1e-12)
    np.testing.assert_allclose(avatar.positions, PchipInterpolator(t, a)(grid), atol=1e-12)
    with pytest.raises(InputError, match=r"\(human, avatar\), expected one: name one player in"):
        read_trial(path, options)


def test_without_resample_the_recorded_times_are_kept(tmp_path) -> None:
    t, h, a = jittered()
    path = tmp_path / "trial.csv"
    pd.DataFrame({"time": t, "h": h, "a": a}).to_csv(path, index=False)
    (human,) = read_trial_file(path, ImportOptions(columns=parse_columns("time=time,me=h")))
    np.testing.assert_array_equal(human.times, t)
    np.testing.assert_array_equal(human.positions, h)
    assert "resampled_from" not in human.metadata


def test_a_missing_column_names_the_options(tmp_path) -> None:
    t, h, a = jittered()
    path = tmp_path / "trial.csv"
    pd.DataFrame({"time": t, "h": h, "a": a}).to_csv(path, index=False)
    with pytest.raises(InputError, match="--columns") as caught:
        read_trial_file(path, ImportOptions(columns=parse_columns("time=time,human=human")))
    assert "'human'" in caught.value.problem and "'h'" in caught.value.problem
