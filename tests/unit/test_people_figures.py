"""Figures of many people stay readable (issue 39.3: labels overlapped in similarity.png)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from matplotlib.text import Text

from mirror_avatar.figures.people import plot_emd_heatmap, plot_people_space
from mirror_avatar.report import render_png
from mirror_avatar.signatures.signature import DEFAULT_BINS, SignatureAnalysis, confidence_ellipse


def crowded_analysis(n_people: int, n_trials: int, seed: int = 0) -> SignatureAnalysis:
    """People whose trials crowd one corner of the similarity space, with long names."""
    rng = np.random.default_rng(seed)
    centres = rng.normal(scale=0.01, size=(n_people, 2))
    coordinates = np.repeat(centres, n_trials, axis=0) + rng.normal(
        scale=0.002, size=(n_people * n_trials, 2)
    )
    groups = [f"participant_{p:02d}" for p in range(n_people) for _ in range(n_trials)]
    names = list(dict.fromkeys(groups))
    emd = np.linalg.norm(coordinates[:, None] - coordinates[None], axis=2)
    analysis = SignatureAnalysis(
        labels=[f"trial_{k:02d}" for _ in range(n_people) for k in range(n_trials)],
        groups=groups,
        group_names=names,
        bins=DEFAULT_BINS,
        ims=np.zeros((len(groups), DEFAULT_BINS.n)),
        group_ims=np.zeros((n_people, DEFAULT_BINS.n)),
        emd=emd,
        coordinates=coordinates,
        ellipses={},
        overlaps=np.zeros((n_people, n_people)),
        strokes=[np.empty((0, 2))] * len(groups),
        stroke_ellipses={},
        level=0.7,
        rate=100.0,
    )
    analysis.ellipses = {
        g: confidence_ellipse(xy) if len(xy) >= 3 else None
        for g, xy in analysis.points_by_group().items()
    }
    return analysis


def boxes(texts: list[Text]):
    renderer = texts[0].get_figure().canvas.get_renderer()
    return [text.get_window_extent(renderer) for text in texts]


@pytest.mark.parametrize(("n_people", "n_trials"), [(7, 5), (30, 3)])
def test_each_person_is_named_once_and_no_names_overlap(n_people, n_trials) -> None:
    analysis = crowded_analysis(n_people, n_trials)
    figure = plot_people_space(analysis)
    figure.draw_without_rendering()
    (axes,) = figure.axes
    assert sorted(t.get_text() for t in axes.texts) == analysis.group_names
    frame = axes.get_window_extent()
    labels = boxes(axes.texts)
    for a, b in itertools.combinations(labels, 2):
        assert not a.overlaps(b)
    for box in labels:
        assert frame.x0 <= box.x0 and box.x1 <= frame.x1
        assert frame.y0 <= box.y0 and box.y1 <= frame.y1
    points = axes.transData.transform(analysis.coordinates)
    covered = [any(box.contains(*xy) for box in labels) for xy in points]
    assert not any(covered)
    assert render_png(figure).startswith(b"\x89PNG")


def test_the_heatmap_names_every_trial_without_overlap() -> None:
    analysis = crowded_analysis(40, 3)
    figure = plot_emd_heatmap(analysis)
    figure.draw_without_rendering()
    axes = figure.axes[0]
    rows = [t for t in axes.get_yticklabels() if t.get_text()]
    assert [t.get_text() for t in rows][:2] == [
        "participant_00/trial_00",
        "participant_00/trial_01",
    ]
    assert len(rows) == 120
    for a, b in itertools.pairwise(boxes(rows)):
        assert not a.overlaps(b)
    columns = boxes([t for t in axes.get_xticklabels() if t.get_text()])
    for a, b in itertools.pairwise(columns):
        assert not a.overlaps(b)


def test_a_few_trials_get_their_emd_written_in_the_cells() -> None:
    analysis = crowded_analysis(3, 3)
    figure = plot_emd_heatmap(analysis)
    values = [float(t.get_text()) for t in figure.axes[0].texts]
    assert len(values) == 81
    np.testing.assert_allclose(values[1], analysis.emd[0, 1], atol=5e-4)
