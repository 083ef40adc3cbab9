import json

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.stats
from hypothesis import given, settings
from hypothesis import strategies as st

from mirror_avatar.common.errors import InputError
from mirror_avatar.signatures.signature import (
    Bins,
    Ellipse,
    analyse_signatures,
    classical_mds,
    compute_emd,
    compute_emd_matrix,
    compute_ims,
    compute_stroke_moments,
    confidence_ellipse,
    ellipse_overlap,
    stroke_moments,
    velocity_strokes,
)

SMALL = Bins(n=24, lo=-1.0, hi=1.0)


def uniform_on(bins, first, width):
    p = np.zeros(bins.n)
    p[first : first + width] = 1.0 / width
    return p


# --- IMS and EMD -------------------------------------------------------------------------------


def test_ims_counts_outliers_in_end_bins():
    p = compute_ims([-10.0, 0.0, 10.0, 3.5])
    assert p.sum() == pytest.approx(1.0)
    assert p[0] == pytest.approx(1 / 4) and p[-1] == pytest.approx(2 / 4)


@pytest.mark.parametrize("shift", [1, 7, 40])
def test_emd_of_shifted_uniforms_is_shift_over_range(shift):
    bins = Bins()
    p, q = uniform_on(bins, 50, 30), uniform_on(bins, 50 + shift, 30)
    expected = shift * bins.width / (bins.hi - bins.lo)
    assert compute_emd(p, q, bins) == pytest.approx(expected, rel=1e-12)
    scipy_value = scipy.stats.wasserstein_distance(
        bins.centres, bins.centres, u_weights=p, v_weights=q
    ) / (bins.hi - bins.lo)
    assert compute_emd(p, q, bins) == pytest.approx(scipy_value, rel=1e-9)


densities = st.lists(
    st.floats(min_value=0.0, max_value=1.0), min_size=SMALL.n, max_size=SMALL.n
).filter(lambda w: sum(w) > 1e-3)


def normalised(weights):
    w = np.asarray(weights)
    return w / w.sum()


@settings(max_examples=60, deadline=None)
@given(densities, densities, densities)
def test_emd_is_a_metric_in_unit_interval(a, b, c):
    p, q, r = normalised(a), normalised(b), normalised(c)
    pq = compute_emd(p, q, SMALL)
    assert pq == pytest.approx(compute_emd(q, p, SMALL), abs=1e-15)
    assert compute_emd(p, p, SMALL) == 0.0
    assert 0.0 <= pq <= 1.0
    assert pq <= compute_emd(p, r, SMALL) + compute_emd(r, q, SMALL) + 1e-12
    scipy_value = scipy.stats.wasserstein_distance(
        SMALL.centres, SMALL.centres, u_weights=p, v_weights=q
    ) / (SMALL.hi - SMALL.lo)
    assert pq == pytest.approx(scipy_value, abs=1e-12)


def test_emd_of_opposite_end_masses_is_one():
    p, q = np.zeros(SMALL.n), np.zeros(SMALL.n)
    p[0], q[-1] = 1.0, 1.0
    assert compute_emd(p, q, SMALL) == pytest.approx(1.0)


def test_emd_matrix_equals_pairwise_calls(rng):
    signatures = rng.dirichlet(np.ones(SMALL.n), size=7)
    others = rng.dirichlet(np.ones(SMALL.n), size=4)
    matrix = compute_emd_matrix(signatures, others, bins=SMALL)
    expected = [[compute_emd(p, q, SMALL) for q in others] for p in signatures]
    np.testing.assert_allclose(matrix, expected, rtol=1e-12)


# --- classical MDS -----------------------------------------------------------------------------


def test_classical_mds_recovers_planar_configuration(rng):
    truth = rng.normal(size=(12, 2)) * [3.0, 1.0]
    distances = np.linalg.norm(truth[:, None] - truth[None], axis=2)
    found = classical_mds(distances, 2)
    centred = truth - truth.mean(axis=0)
    rotation, _ = scipy.linalg.orthogonal_procrustes(found, centred)
    np.testing.assert_allclose(found @ rotation, centred, atol=1e-9)
    np.testing.assert_allclose(
        np.linalg.norm(found[:, None] - found[None], axis=2), distances, atol=1e-9
    )


def test_classical_mds_is_deterministic_and_clips_negative_eigenvalues(rng):
    # Distances of 4 points at equal mutual distance except one: not Euclidean in 1-D.
    distances = np.ones((4, 4)) - np.eye(4)
    distances[0, 1] = distances[1, 0] = 1.9
    first = classical_mds(distances, 3)
    assert np.all(np.isfinite(first))
    np.testing.assert_array_equal(first, classical_mds(distances.copy(), 3))
    largest = first[np.argmax(np.abs(first), axis=0), np.arange(3)]
    assert np.all(largest >= 0)


def test_classical_mds_rejects_non_square():
    with pytest.raises(InputError):
        classical_mds(np.ones((3, 4)))


# --- ellipses ----------------------------------------------------------------------------------


def make_ellipse(centre, a, b, angle):
    c, s = np.cos(angle), np.sin(angle)
    return Ellipse(np.asarray(centre, float), np.array([[c, -s], [s, c]]), np.array([a, b]), 0.7)


def test_ellipse_polygon_area_is_pi_a_b():
    ellipse = make_ellipse([1.0, -2.0], 3.0, 0.5, 0.6)
    assert ellipse.area == pytest.approx(np.pi * 1.5)
    assert ellipse.polygon().area == pytest.approx(np.pi * 1.5, rel=1e-3)


def test_identical_and_disjoint_ellipses():
    a = make_ellipse([0.0, 0.0], 2.0, 1.0, 0.3)
    assert ellipse_overlap(a, a) == pytest.approx(1.0)
    assert ellipse_overlap(a, make_ellipse([10.0, 0.0], 2.0, 1.0, 0.3)) == 0.0


@pytest.mark.parametrize("d", [0.2, 1.0, 1.7])
def test_overlap_of_unit_circles_is_lens_over_union(d):
    lens = 2 * np.arccos(d / 2) - (d / 2) * np.sqrt(4 - d**2)
    expected = lens / (2 * np.pi - lens)
    a = make_ellipse([0.0, 0.0], 1.0, 1.0, 0.0)
    b = make_ellipse([d, 0.0], 1.0, 1.0, 0.0)
    assert ellipse_overlap(a, b) == pytest.approx(expected, rel=1e-3)


@pytest.mark.parametrize("level", [0.5, 0.7, 0.95])
def test_confidence_ellipse_covers_level_of_gaussian_points(rng, level):
    covariance = np.array([[2.0, 0.8], [0.8, 0.6]])
    points = rng.multivariate_normal([1.0, -1.0], covariance, size=40_000)
    ellipse = confidence_ellipse(points, level)
    local = (points - ellipse.centre) @ ellipse.axes / ellipse.semi_axes
    inside = np.mean((local**2).sum(axis=1) <= 1.0)
    assert inside == pytest.approx(level, abs=0.01)
    assert ellipse.semi_axes[0] >= ellipse.semi_axes[1]


def test_confidence_ellipse_needs_three_points():
    with pytest.raises(InputError):
        confidence_ellipse(np.zeros((2, 2)))


# --- strokes -----------------------------------------------------------------------------------


def half_sine_kurtosis():
    # density (pi/2) sin(pi t) on [0, 1]; with u = t - 1/2 its moments are integrals of
    # u^k (pi/2) cos(pi u), done by parts.
    variance = 1 / 4 - 2 / np.pi**2
    fourth = 1 / 16 - 3 / np.pi**2 + 24 / np.pi**4
    return fourth / variance**2


def test_half_sine_kurtosis_formula_matches_quadrature():
    def moment(k):
        return scipy.integrate.quad(lambda t: (t - 0.5) ** k * np.pi / 2 * np.sin(np.pi * t), 0, 1)[
            0
        ]

    assert half_sine_kurtosis() == pytest.approx(moment(4) / moment(2) ** 2, rel=1e-10)
    assert half_sine_kurtosis() == pytest.approx(2.19, abs=0.005)


def test_half_sine_stroke_moments():
    stroke = np.sin(np.pi * np.linspace(0.0, 1.0, 2001)) * 0.8
    skewness, kurtosis = compute_stroke_moments(stroke)
    assert skewness == pytest.approx(0.0, abs=1e-9)
    assert kurtosis == pytest.approx(half_sine_kurtosis(), rel=1e-5)
    assert compute_stroke_moments(-stroke) == pytest.approx((skewness, kurtosis))


def test_skewed_stroke_has_positive_skewness():
    t = np.linspace(0.0, 1.0, 500)
    early_peak = t * (1 - t) ** 3
    assert compute_stroke_moments(early_peak)[0] > 0.3


def test_strokes_of_a_sine_drop_incomplete_ends():
    rate, frequency = 100.0, 0.5
    t = np.arange(0, 10.3, 1 / rate)
    strokes = velocity_strokes(np.sin(2 * np.pi * frequency * t + 0.3))
    # Half-periods of 1 s; the partial first and last are left out.
    assert len(strokes) == 9
    assert all(abs(s.size - 100) <= 1 for s in strokes)
    moments = stroke_moments(np.sin(2 * np.pi * frequency * t + 0.3))
    assert moments.shape == (9, 2)
    np.testing.assert_allclose(moments[:, 1], half_sine_kurtosis(), rtol=2e-3)


def test_strokes_with_flat_runs():
    up, down = np.sin(np.linspace(0, np.pi, 60)[1:-1]), -np.sin(np.linspace(0, np.pi, 60)[1:-1])
    pause = np.zeros(30)
    # A pause inside a stroke does not split it; a pause between opposite strokes ends one.
    inside = np.concatenate([down, up[:29], pause, up[29:], down, up])
    lengths = [s.size for s in velocity_strokes(inside)]
    assert lengths == [58 + 30, 58]
    between = np.concatenate([pause, down, pause, up, pause, down, up])
    lengths = [s.size for s in velocity_strokes(between)]
    # Leading pause + down + pause is the incomplete first segment; the last up is incomplete.
    assert lengths == [58 + 30, 58]
    assert velocity_strokes(np.zeros(500)) == []
    assert stroke_moments(np.zeros(500)).shape == (0, 2)


def test_short_strokes_are_dropped():
    v = np.tile(np.r_[np.ones(10), -np.ones(10)], 10)
    assert velocity_strokes(v, min_samples=20) == []
    assert len(velocity_strokes(v, min_samples=10)) == 18


# --- analysis on the bundled real data ---------------------------------------------------------


@pytest.fixture(scope="module")
def analysis():
    from mirror_avatar.datasets import load_zhai2017

    return analyse_signatures(load_zhai2017())


def test_styles_are_closer_within_than_between(analysis):
    groups = np.asarray(analysis.groups)
    upper = np.triu(np.ones_like(analysis.emd, dtype=bool), 1)
    same = groups[:, None] == groups[None]
    within, between = analysis.emd[upper & same].mean(), analysis.emd[upper & ~same].mean()
    assert 3 * within < between
    # README of the data: within fast ~0.025, within slow ~0.005, between ~0.09.
    fast, slow = analysis.members("fast"), analysis.members("slow")
    assert analysis.emd[np.ix_(fast, fast)][np.triu_indices(9, 1)].mean() == pytest.approx(
        0.025, abs=0.005
    )
    assert analysis.emd[np.ix_(slow, slow)][np.triu_indices(9, 1)].mean() == pytest.approx(
        0.005, abs=0.002
    )
    assert between == pytest.approx(0.09, abs=0.01)


def test_analysis_shapes_and_json(analysis):
    m = len(analysis.labels)
    assert m == 18 and analysis.group_names == ["fast", "slow"]
    assert analysis.ims.shape == (m, 200) and analysis.group_ims.shape == (2, 200)
    assert analysis.coordinates.shape == (m, 2)
    assert analysis.overlaps.shape == (2, 2)
    np.testing.assert_allclose(np.diag(analysis.overlaps), 1.0)
    assert analysis.overlaps[0, 1] < 0.2
    stats = analysis.stroke_statistics()
    for group in ("fast", "slow"):
        assert stats[group]["n_strokes"] > 50
        assert -0.5 < stats[group]["skewness_mean"] < 0.5
        assert 1.5 < stats[group]["kurtosis_mean"] < 3.0
    text = json.dumps(analysis.to_json_dict(), allow_nan=False)
    assert json.loads(text)["labels"][0] == "fast-1"


def test_analysis_needs_two_trials_and_skips_ellipses_below_three(zhai_trials):
    with pytest.raises(InputError, match="at least 2 trials"):
        analyse_signatures(zhai_trials[:1])
    analysis = analyse_signatures(zhai_trials[:2])
    assert analysis.emd.shape == (2, 2) and analysis.ellipses == {"fast": None}
    assert np.isnan(analysis.overlaps).all()
