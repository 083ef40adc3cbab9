import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.patches import StepPatch

from mirror_avatar.figures.sessions import plot_relative_phase
from mirror_avatar.figures.signatures import plot_ims, plot_similarity_space, plot_skew_kurtosis
from mirror_avatar.report import render_png
from mirror_avatar.signatures.signature import DEFAULT_BINS, confidence_ellipse


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
    figure = plot_similarity_space(points, ellipses)
    (axes,) = figure.axes
    assert len(axes.collections) == 2
    assert len(axes.patches) == 1
    assert render_png(figure).startswith(b"\x89PNG")


def test_plot_skew_kurtosis_with_human_range(rng):
    moments = {"slow": rng.normal([0, 2.3], 0.2, size=(50, 2)), "empty": np.empty((0, 2))}
    ellipses = {"slow": confidence_ellipse(moments["slow"])}
    figure = plot_skew_kurtosis(moments, ellipses)
    (axes,) = figure.axes
    assert len(axes.patches) == 2
    assert len(plot_skew_kurtosis(moments, show_human_range=False).axes[0].patches) == 0
    assert render_png(figure).startswith(b"\x89PNG")


def test_plot_relative_phase_draws_densities_and_circular_means(rng):
    phases = {
        "locked": rng.vonmises(0.5, 8.0, size=4000),
        "across pi": rng.vonmises(3.0, 8.0, 4000),
    }
    figure = plot_relative_phase(phases, n_bins=36)
    (axes,) = figure.axes
    assert len(axes.patches) == 2
    for patch in axes.patches:
        assert isinstance(patch, StepPatch)
        values, edges, _ = patch.get_data()
        assert np.sum(values * np.diff(edges)) == pytest.approx(1.0)
    means = [float(np.asarray(line.get_xdata())[0]) for line in axes.lines]
    assert means[0] == pytest.approx(0.5, abs=0.03)
    assert abs(means[1]) == pytest.approx(3.0, abs=0.03)
    assert render_png(figure).startswith(b"\x89PNG")


def test_moving_mean_matches_a_slow_loop() -> None:
    from mirror_avatar.figures.sessions import moving_mean

    x = np.random.default_rng(3).random(57)
    for n in (1, 4, 5, 200):
        half_left, half_right = (n - 1) // 2, n // 2
        expected = [x[max(0, i - half_right) : i + half_left + 1].mean() for i in range(x.size)]
        np.testing.assert_allclose(moving_mean(x, n), expected, rtol=1e-12)


def test_group_synchronisation_is_drawn_smoothed_with_a_legend() -> None:
    from mirror_avatar.figures.sessions import moving_mean, plot_group_synchronisation

    t = np.arange(0, 20, 0.01)
    rho = 0.7 + 0.3 * np.sign(np.sin(2 * np.pi * 7 * t))  # flickers every sample or so
    figure = plot_group_synchronisation(t, {"with VT5": rho})
    (axes,) = figure.axes
    raw, smooth = axes.lines
    np.testing.assert_allclose(smooth.get_ydata(), moving_mean(rho, 200))
    assert np.ptp(smooth.get_ydata()[300:-300]) < 0.1 * np.ptp(raw.get_ydata())
    assert [text.get_text() for text in axes.get_legend().get_texts()] == ["with VT5"]


def test_a_legend_of_many_people_goes_beside_the_axes_which_keep_their_size() -> None:
    """Issue 39.3: thirty people's legend squeezed the signatures' axes to a strip."""
    from mirror_avatar.figures.style import FIGSIZE

    signatures = {f"participant_{k:02d}": np.full(DEFAULT_BINS.n, 1 / DEFAULT_BINS.n)
                  for k in range(30)}  # fmt: skip
    figure = plot_ims(signatures)
    figure.draw_without_rendering()
    (axes,) = figure.axes
    legend = axes.get_legend().get_window_extent()
    frame = axes.get_window_extent()
    assert legend.x0 >= frame.x1 and len(axes.get_legend().get_texts()) == 30
    assert frame.width / figure.dpi > 0.6 * FIGSIZE[0]
    assert frame.height / figure.dpi > 0.6 * FIGSIZE[1]
    few = plot_ims({"fast": signatures["participant_00"]})
    few.draw_without_rendering()
    assert few.axes[0].get_legend().get_window_extent().x1 <= few.axes[0].get_window_extent().x1
