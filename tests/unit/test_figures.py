import numpy as np
from matplotlib.figure import Figure

from mirror_avatar.figures import plot_ims, plot_similarity_space, plot_skew_kurtosis
from mirror_avatar.report import render_png
from mirror_avatar.signature import DEFAULT_BINS, confidence_ellipse


def test_plot_ims_draws_one_curve_per_group_and_trial(rng):
    groups = {"fast": rng.dirichlet(np.ones(200)), "fast (generated)": rng.dirichlet(np.ones(200))}
    trials = {"fast": rng.dirichlet(np.ones(200), size=3)}
    figure = plot_ims(groups, DEFAULT_BINS, trial_ims=trials)
    assert isinstance(figure, Figure)
    (axes,) = figure.axes
    assert len(axes.lines) == 5
    legend = [text.get_text() for text in axes.get_legend().get_texts()]
    assert legend == ["fast", "fast (generated)"]
    curve = axes.lines[3]
    np.testing.assert_allclose(curve.get_ydata(), groups["fast"] / DEFAULT_BINS.width)
    assert render_png(figure).startswith(b"\x89PNG")


def test_plot_similarity_space_draws_points_and_ellipses(rng):
    points = {"a": rng.normal(size=(6, 2)), "b": rng.normal(size=(2, 2)) + 5}
    ellipses = {"a": confidence_ellipse(points["a"]), "b": None}
    figure = plot_similarity_space(points, ellipses, labels={"a": list("uvwxyz")})
    (axes,) = figure.axes
    assert len(axes.collections) == 2
    assert len(axes.patches) == 1
    assert len(axes.texts) == 6
    assert render_png(figure).startswith(b"\x89PNG")


def test_plot_skew_kurtosis_with_human_range(rng):
    moments = {"slow": rng.normal([0, 2.3], 0.2, size=(50, 2)), "empty": np.empty((0, 2))}
    ellipses = {"slow": confidence_ellipse(moments["slow"])}
    figure = plot_skew_kurtosis(moments, ellipses)
    (axes,) = figure.axes
    assert len(axes.patches) == 2
    assert len(plot_skew_kurtosis(moments, show_human_range=False).axes[0].patches) == 0
    assert render_png(figure).startswith(b"\x89PNG")
