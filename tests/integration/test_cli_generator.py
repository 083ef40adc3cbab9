"""``mirror-avatar generator fit`` and ``sample`` end to end."""

import json

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.files.trial_io import read_csv_trial, write_csv_trial
from mirror_avatar.motion.generator import IMSGenerator


@pytest.fixture(scope="module")
def model_path(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("model") / "slow.npz"
    assert (
        main(
            [
                "generator",
                "fit",
                "--bundled",
                "slow",
                "--kind",
                "ims",
                "--symbols",
                "32",
                "--out",
                str(path),
            ]
        )
        == 0
    )
    return str(path)


def test_fit_on_bundled_style(model_path: str) -> None:
    model = IMSGenerator.load(model_path)
    assert model.n_symbols == 32 and model.random_state == 0
    assert model.training_summary_["groups"] == ["slow"]
    assert len(model.training_summary_["labels"]) == 9


def test_fit_on_files_with_sweep(zhai_trials, tmp_path, capsys) -> None:
    folder = tmp_path / "fast"
    folder.mkdir()
    for trial in zhai_trials[:4]:
        write_csv_trial(trial, folder / f"{trial.label}.csv")
    out = tmp_path / "fast.npz"
    args = [
        "generator",
        "fit",
        str(folder),
        "--kind",
        "ims",
        "--symbols",
        "16",
        "--seed",
        "3",
        "--out",
        str(out),
    ]
    assert main([*args, "--sweep"]) == 0
    assert IMSGenerator.load(out).training_summary_["labels"] == [f"fast-{k}" for k in range(1, 5)]
    sweep = (tmp_path / "fast.sweep.csv").read_text().splitlines()
    assert sweep[0].startswith("n_symbols,train_distortion")
    assert [line.split(",")[0] for line in sweep[1:]] == ["32", "64", "128", "256"]
    assert "sweep ->" in capsys.readouterr().out


def test_sample_writes_csv_trials(model_path: str, tmp_path) -> None:
    out = tmp_path / "samples"
    args = ["generator", "sample", model_path, "--duration", "5", "--count", "2"]
    assert main([*args, "--out", str(out), "--seed", "7"]) == 0
    manifest = json.loads((out / "samples.json").read_text())
    assert manifest["seed"] == 7 and manifest["files"] == ["generated-001.csv", "generated-002.csv"]
    first = read_csv_trial(out / "generated-001.csv")
    assert first.n_samples == 501 and first.rate == pytest.approx(100.0)
    expected = IMSGenerator.load(model_path).sample(5.0, n=2, random_state=7)[0]
    np.testing.assert_allclose(first.positions, expected.positions, rtol=0, atol=1e-15)
    assert main([*args, "--out", str(tmp_path / "slow10"), "--rate", "10"]) == 0
    assert read_csv_trial(tmp_path / "slow10" / "generated-002.csv").n_samples == 51


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["fit", "--out", "m.npz"], "--bundled"),
        (["fit", "--bundled", "slow", "--out", "m.txt"], "must end in .npz"),
        (
            ["fit", "--bundled", "slow", "--kind", "ims", "--symbols", "1", "--out", "m.npz"],
            "--symbols",
        ),
        (["fit", "missing.csv", "--out", "m.npz"], "no such file"),
        (["sample", "missing.npz", "--out", "s"], "missing.npz"),
        (["sample", "not-a-model.npz", "--out", "s"], "not-a-model.npz"),
    ],
)
def test_bad_input_is_one_line(tmp_path, monkeypatch, capsys, args, fragment) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "not-a-model.npz").write_text("hello")
    assert main(["generator", *args]) == 2
    error = capsys.readouterr().err
    assert fragment in error and error.count("\n") == 1


def test_sample_refuses_bad_counts(model_path: str, tmp_path, capsys) -> None:
    assert main(["generator", "sample", model_path, "--count", "0", "--out", str(tmp_path)]) == 2
    assert "give a whole number in [1, 100000]" in capsys.readouterr().err
