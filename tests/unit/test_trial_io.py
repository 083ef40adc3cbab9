"""Tests of trial file reading and writing."""

from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli.trial_sets import read_trial_set
from mirror_avatar.common.errors import InputError
from mirror_avatar.files.atomic import atomic_path, write_atomic_text
from mirror_avatar.files.trial_files import read_trial, read_trial_file, write_trial
from mirror_avatar.files.trial_io import read_mat_struct, write_mat_struct
from mirror_avatar.files.trials import make_trial


def test_csv_round_trip(tmp_path: Path, rng: np.random.Generator) -> None:
    times = np.cumsum(rng.uniform(0.005, 0.015, 500))  # irregular timestamps
    trial = make_trial(times, 0.3 * np.sin(times), label="a")
    write_trial(trial, tmp_path / "a.csv")
    back = read_trial(tmp_path / "a.csv")
    np.testing.assert_allclose(back.times, trial.times, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.positions, trial.positions, rtol=0, atol=1e-12)


def test_parquet_round_trip_keeps_metadata(tmp_path: Path, rng: np.random.Generator) -> None:
    times = np.cumsum(rng.uniform(0.005, 0.015, 500))
    trial = make_trial(times, 0.3 * np.sin(times), label="p", group="g", metadata={"seed": 7})
    write_trial(trial, tmp_path / "p.parquet")
    back = read_trial(tmp_path / "p.parquet")
    np.testing.assert_allclose(back.positions, trial.positions, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.times, trial.times, rtol=0, atol=1e-12)
    assert (back.label, back.group, back.metadata["seed"]) == ("p", "g", 7)


def test_bids_motion_round_trip(tmp_path: Path) -> None:
    times = np.arange(600) / 100.0
    trial = make_trial(times, 0.3 * np.sin(times), label="mirror")
    path = tmp_path / "sub-01_task-mirror_tracksys-x_motion.tsv"
    write_trial(trial, path)
    back = read_trial(path)
    np.testing.assert_allclose(back.times, times, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.positions, trial.positions, rtol=0, atol=1e-12)
    path.with_suffix(".json").unlink()
    with pytest.raises(InputError, match="no sidecar"):
        read_trial(path)


def test_bundled_mat_reads(zhai_trials: list) -> None:
    assert len(zhai_trials) == 18


def test_mat_round_trip(tmp_path: Path, zhai_trials_100hz: list) -> None:
    trials = zhai_trials_100hz[:3]
    write_mat_struct(trials, tmp_path / "s.mat", "s")
    duration = float(trials[0].times[-1] - trials[0].times[0])
    back = read_mat_struct(tmp_path / "s.mat", duration, variable="s")
    assert len(back) == 3
    for a, b in zip(trials, back, strict=True):
        np.testing.assert_allclose(b.positions, a.positions, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back[0].times + trials[0].times[0], trials[0].times, atol=1e-9)


def test_csv_extra_columns_and_whitespace(tmp_path: Path) -> None:
    rows = "".join(f" {k / 100} , 0.1 , {k}\n" for k in range(200))
    (tmp_path / "b.csv").write_text(" time , position , other\n" + rows)
    trial = read_trial(tmp_path / "b.csv")
    assert trial.positions.size == 200
    assert trial.times[1] == pytest.approx(0.01)


BAD_CSV = {
    "empty": ("", "empty"),
    "misnamed": ("t,position\n0,0\n", "found"),
    "non-numeric": ("time,position\n0,0\n0.01,abc\n", "row 3"),
    "nan": ("time,position\n" + "".join(f"{k / 100},nan\n" for k in range(200)), ""),
    "decreasing": ("time,position\n" + "".join(f"{-k / 100},0\n" for k in range(200)), ""),
    "too-few": ("time,position\n0,0\n", ""),
}


@pytest.mark.parametrize("case", sorted(BAD_CSV))
def test_bad_csv(tmp_path: Path, case: str) -> None:
    text, fragment = BAD_CSV[case]
    path = tmp_path / f"{case}.csv"
    path.write_text(text)
    with pytest.raises(InputError) as error:
        read_trial(path)
    message = str(error.value)
    assert "\n" not in message and path.name in message and fragment in message


@pytest.mark.parametrize("name", ["missing.csv", "x.foo", "corrupt.mat", "foreign.parquet"])
def test_bad_files(tmp_path: Path, name: str) -> None:
    if name != "missing.csv":
        (tmp_path / name).write_bytes(b"\x00\x01garbage")
    with pytest.raises(InputError, match=name.replace(".", r"\.")):
        read_trial_file(tmp_path / name)


def test_empty_directory(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no readable trial file"):
        read_trial_set([tmp_path])


def test_directory_gives_group(tmp_path: Path, zhai_trials_100hz: list) -> None:
    folder = tmp_path / "fast"
    folder.mkdir()
    for k, trial in enumerate(zhai_trials_100hz[:2]):
        write_trial(make_trial(trial.times, trial.positions), folder / f"{k}.csv")
    trials = read_trial_set([folder]).trials
    assert [t.group for t in trials] == ["fast", "fast"]


def test_failed_write_keeps_existing_file(tmp_path: Path) -> None:
    path = tmp_path / "good.txt"
    path.write_text("good")
    with pytest.raises(RuntimeError), atomic_path(path) as temporary:
        temporary.write_text("half")
        raise RuntimeError("boom")
    assert path.read_text() == "good"
    assert list(tmp_path.iterdir()) == [path]


def test_an_overwritten_file_keeps_its_permissions(tmp_path: Path) -> None:
    path = tmp_path / "shared.txt"
    path.write_text("old")
    path.chmod(0o640)
    write_atomic_text(path, "new")
    assert path.read_text() == "new" and path.stat().st_mode & 0o777 == 0o640


def _write_parquet_with_nan(path: Path, gap: int) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    positions = 0.1 * np.sin(np.arange(200) / 20.0)
    positions[50 : 50 + gap] = np.nan
    pq.write_table(pa.table({"time": np.arange(200) / 100.0, "position": positions}), path)


def _write_bids_with_nan(path: Path, gap: int) -> None:
    values = [repr(0.1 * float(np.sin(k / 20.0))) for k in range(200)]
    values[100 : 100 + gap] = ["n/a"] * gap
    path.write_text("\n".join(values) + "\n")
    path.with_name(path.name.replace(".tsv", ".json")).write_text('{"SamplingFrequency": 100}')


@pytest.mark.parametrize(
    ("name", "write"),
    [("nan.parquet", _write_parquet_with_nan), ("sub-01_task-x_motion.tsv", _write_bids_with_nan)],
)
def test_drop_outs_in_binary_and_bids_files(tmp_path: Path, name: str, write) -> None:
    """A short drop-out is interpolated (linearly) and recorded; a long one is refused."""
    path = tmp_path / name
    write(path, 3)
    trial = read_trial(path)
    assert trial.metadata["import"]["interpolated_samples"] == 3
    assert np.all(np.isfinite(trial.positions)) and trial.n_samples == 200
    write(path, 40)
    with pytest.raises(InputError) as error:
        read_trial(path)
    message = str(error.value)
    assert "\n" not in message and name in message and "--max-gap" in message
