"""The generator validation experiment (paper VI-A) on the bundled trials."""

import numpy as np
import pytest
from shapely.geometry import Point

from mirror_avatar.common.errors import InputError
from mirror_avatar.experiments import EXPERIMENTS
from mirror_avatar.experiments.generator import fraction_inside, run, split_and_generate
from mirror_avatar.report import Section
from mirror_avatar.signatures.signature import analyse_signatures


@pytest.fixture(scope="module")
def section(zhai_trials) -> Section:
    return run(zhai_trials, quick=True, seed=0)


@pytest.mark.long
def test_generated_motion_passes_every_check(section: Section) -> None:
    _check(section, seed=0)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_generated_motion_passes_every_check_for_other_seeds(zhai_trials, seed: int) -> None:
    _check(run(zhai_trials, quick=True, seed=seed), seed)


def _check(section: Section, seed: int) -> None:
    metrics = section.metrics
    assert metrics["checks"] == {
        "emd_within_1.5x_human": True,
        "emd_below_half_between": True,
        "all_identified": True,
        "strokes_within_one_sd": True,
    }
    assert metrics["identification_accuracy"] == 1.0 and metrics["seed"] == seed
    for style, row in metrics["style_emd"].items():
        assert row["generated_vs_held_out"] < row["generated_vs_other_styles"], style
        assert len(metrics["split"][style]["train"]) == 6
        assert len(metrics["split"][style]["held_out"]) == 3
    for style, row in metrics["smoothing"].items():
        ratio = row["generated_acceleration_rms"] / row["human_acceleration_rms"]
        assert row["acceleration_ratio"] == pytest.approx(ratio)
        assert 0.5 < row["acceleration_ratio"] < 1.5 and 0.7 < row["velocity_ratio"] < 1.3, style
    assert len(section.figures) == 3 and len(section.tables) == 5


@pytest.mark.long
def test_split_is_reproducible_and_disjoint(zhai_trials, section: Section) -> None:
    again = split_and_generate(zhai_trials, seed=0)
    everything = [t for sp in again.values() for t in sp.train + sp.held_out + sp.generated]
    analysis = analyse_signatures(everything)
    for style in again:
        region = analysis.ellipses[style].polygon()
        points = analysis.points_by_group()[f"{style} (generated)"]
        expected = np.mean([region.contains(Point(p)) for p in points])
        share = fraction_inside(analysis, style, f"{style} (generated)")
        assert share == expected == section.metrics["generated_inside_human_region"][style]
    for style, parts in section.metrics["split"].items():
        assert parts["train"] == [t.label for t in again[style].train]
        assert parts["held_out"] == [t.label for t in again[style].held_out]
        assert not set(parts["train"]) & set(parts["held_out"])
        assert all(t.label.startswith(style) for t in again[style].train)
        assert [t.group for t in again[style].generated] == [f"{style} (generated)"] * 3


def test_codebook_sweep_rows(section: Section) -> None:
    sweep = section.metrics["codebook_sweep"]
    assert [(r["style"], r["n_symbols"]) for r in sweep] == [
        ("fast", 32),
        ("fast", 128),
        ("slow", 32),
        ("slow", 128),
    ]
    for small, large in zip(sweep[::2], sweep[1::2], strict=True):
        assert large["train_distortion"] < small["train_distortion"]
        assert np.isfinite(large["emd_to_test"])


def test_registered_after_signature() -> None:
    names = [name for name, _ in EXPERIMENTS]
    assert names.index("generator") == names.index("signature") + 1


def test_one_style_is_refused(zhai_trials) -> None:
    with pytest.raises(InputError, match="2 groups"):
        run([t for t in zhai_trials if t.group == "fast"], quick=True)
