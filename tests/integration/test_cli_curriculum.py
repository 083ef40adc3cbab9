"""``mirror-avatar curriculum``: stage files that every SPEC and ``generator sample`` take."""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np
import pytest

from mirror_avatar.cli import main
from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.model_files import load_model, save_model
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.motion.strokes import StrokeGenerator
from mirror_avatar.players import VirtualTrainer
from mirror_avatar.specs import load_player
from mirror_avatar.training.curriculum import StageMotion, load_stage


@pytest.fixture(scope="module")
def stages(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("curriculum")
    trials = load_zhai2017()
    IMSGenerator(n_symbols=32, random_state=0).fit(trials[9:13]).save(folder / "patient.npz")
    IMSGenerator(n_symbols=32, random_state=0).fit(trials[:4]).save(folder / "target.npz")
    out = folder / "out"
    assert main(["curriculum", "--patient", str(folder / "patient.npz"), "--target",
                 str(folder / "target.npz"), "--stages", "3", "--out", str(out)]) == 0  # fmt: skip
    return out


def test_the_plan_moves_from_the_patient_to_the_target(stages: Path) -> None:
    plan = json.loads((stages / "plan.json").read_text())
    assert plan["method"] == "displacement" and [s["file"] for s in plan["stages"]] == [
        "stage-1.npz", "stage-2.npz", "stage-3.npz",
    ]  # fmt: skip
    assert [s["weight"] for s in plan["stages"]] == [0.0, 0.5, 1.0]
    assert np.all(np.diff([s["EMD to patient"] for s in plan["stages"]]) > 0)
    assert np.all(np.diff([s["EMD to target"] for s in plan["stages"]]) < 0)
    page = html.unescape((stages / "report.html").read_text())
    assert "Rehabilitation curriculum" in page
    # issue 39.3: the report leads with its verdict
    lead = page[page.index('<p class="lead">') :]
    assert lead.index("within the patient's variability") < lead.index("<section")


def test_a_stage_is_a_spec_and_a_sampler(stages: Path, tmp_path: Path) -> None:
    stage = load_stage(stages / "stage-2.npz")
    assert isinstance(stage, StageMotion) and stage.weight == 0.5
    player = load_player(str(stages / "stage-2.npz"), "leader")
    assert isinstance(player, VirtualTrainer) and isinstance(player.reference, StageMotion)
    out = tmp_path / "samples"
    args = ["generator", "sample", str(stages / "stage-2.npz"), "--count", "2", "--duration", "5"]
    assert main([*args, "--out", str(out)]) == 0
    rows = np.loadtxt(out / "generated-001.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(np.diff(rows[:, 0]), 0.01, atol=1e-9)
    assert rows[-1, 0] >= 5.0 and np.all(np.abs(rows[:, 1]) <= 0.5)


def test_a_crafted_stage_is_refused_in_one_line(stages: Path, tmp_path: Path) -> None:
    arrays, info = load_model(stages / "stage-2.npz", "mirror-avatar/curriculum-stage", 1, ())
    info = {k: v for k, v in info.items() if k not in ("format", "version", "library_version")}
    crafted = tmp_path / "crafted.npz"
    save_model(crafted, "mirror-avatar/curriculum-stage", 1, arrays, info | {"weight": 1e308})
    with pytest.raises(InputError, match="weight 1e\\+308 is outside"):
        load_stage(crafted)


def test_too_few_stages_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    arguments = ["curriculum", "--patient", "bundled:slow", "--target", "bundled:fast",
                 "--stages", "1", "--out", str(tmp_path / "o")]  # fmt: skip
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "give a whole number in [2, 50]" in error


def test_a_stroke_generator_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Stages blend IMS generators: the default kind of ``generator fit`` is refused, saying so."""
    StrokeGenerator(random_state=0).fit(load_zhai2017()[9:12]).save(tmp_path / "patient.npz")
    arguments = ["curriculum", "--patient", str(tmp_path / "patient.npz"), "--target",
                 "bundled:fast", "--out", str(tmp_path / "o")]  # fmt: skip
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "is a stroke generator" in error and "--kind ims" in error
    assert not (tmp_path / "o").exists()
