"""Tests of the IMS generator: chain estimation, sampling, persistence, and real-data validation."""

from pathlib import Path

import numpy as np
import pytest
from scipy.signal import butter, sosfilt_zi, sosfiltfilt
from sklearn.metrics import pairwise_distances_argmin

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.model_files import save_model
from mirror_avatar.files.trials import (
    _zero_phase_columns,
    compute_velocity,
    make_trial,
    zero_phase_filter,
)
from mirror_avatar.motion.codebook_size import (
    choose_n_symbols,
    one_standard_error_rule,
    sweep_codebook,
)
from mirror_avatar.motion.generator import FORMAT_NAME, FORMAT_VERSION, PAPER_SYMBOLS, IMSGenerator
from mirror_avatar.motion.markov import (
    count_transitions,
    emit_exemplars,
    estimate_transitions,
    group_members,
    sample_chain,
)
from mirror_avatar.signatures.signature import compute_emd, compute_ims, stroke_moments


@pytest.fixture(scope="module")
def small_model(zhai_trials_100hz: list) -> IMSGenerator:
    return IMSGenerator(n_symbols=32, random_state=0).fit(zhai_trials_100hz[9:12])


def test_chain_fitted_to_a_known_sequence_recovers_its_frequencies() -> None:
    rng = np.random.default_rng(5)
    truth = np.array([[0.1, 0.6, 0.3], [0.5, 0.25, 0.25], [0.2, 0.2, 0.6]])
    cumulative = np.cumsum(truth, axis=1)
    sequence = sample_chain(cumulative, np.array([1.0, 1.0, 1.0]), rng.random(200_000))
    estimate = estimate_transitions(count_transitions([sequence], 3), pseudo_count=1e-3)
    np.testing.assert_allclose(estimate, truth, atol=0.01)


def test_transition_rows_are_distributions_even_for_unseen_states() -> None:
    counts = count_transitions([np.array([0, 1, 0, 1, 1])], 4)
    matrix = estimate_transitions(counts, pseudo_count=1e-3)
    np.testing.assert_allclose(matrix.sum(axis=1), 1.0)
    np.testing.assert_allclose(matrix[3], 0.25)
    assert counts[0, 1] == 2 and counts[1, 1] == 1 and counts[1, 0] == 1


def test_fitted_model_shapes_and_diagnostics(small_model: IMSGenerator, zhai_trials_100hz) -> None:
    assert small_model.codebook_.shape == (32, 60)
    np.testing.assert_allclose(small_model.transmat_.sum(axis=1), 1.0)
    assert small_model.startprob_.sum() == pytest.approx(1.0)
    score = small_model.score(zhai_trials_100hz[9:12])
    assert score["distortion"] == pytest.approx(small_model.training_summary_["distortion"])
    assert 0 < score["symbols_used"] <= 1 and score["log_likelihood"] < 0


def test_samples_are_clean_and_reproducible(small_model: IMSGenerator) -> None:
    trials = small_model.sample(20.0, n=2, random_state=3)
    again = small_model.sample(20.0, n=2, random_state=3)
    assert [t.n_samples for t in trials] == [2001, 2001]
    for trial, other in zip(trials, again, strict=True):
        np.testing.assert_array_equal(trial.positions, other.positions)
        assert np.all(np.isfinite(trial.positions)) and np.all(np.abs(trial.positions) <= 0.5)
    assert not np.array_equal(trials[0].positions, trials[1].positions)


def test_no_edge_artefacts(small_model: IMSGenerator) -> None:
    velocity = small_model.sample_velocity(3000, random_state=1)
    edge, inside = np.abs(velocity[:30]).mean(), np.abs(velocity[30:-30]).mean()
    assert edge > 0.2 * inside  # the window taper would pull the ends towards zero
    positions = small_model.sample_positions(3000, random_state=1)
    assert np.abs(np.diff(positions[:30])).max() < 5 * np.abs(np.diff(positions)).mean() + 0.01


def test_save_load_round_trip_samples_identically(small_model: IMSGenerator, tmp_path: Path):
    small_model.save(tmp_path / "m.npz")
    loaded = IMSGenerator.load(tmp_path / "m.npz")
    np.testing.assert_array_equal(
        loaded.sample_velocity(1000, 9), small_model.sample_velocity(1000, 9)
    )
    assert loaded.training_summary_ == small_model.training_summary_


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[:200])


def _foreign(path: Path) -> None:
    np.savez(path, codebook=np.zeros(3))


def _text(path: Path) -> None:
    path.write_text("not a model")


def _bad_rows(path: Path) -> None:
    model = IMSGenerator.load(path)
    model.transmat_ = model.transmat_ * 2
    model.save(path)


@pytest.mark.parametrize(
    ("damage", "fragment"),
    [(_truncate, "readable"), (_foreign, "no metadata"), (_text, "readable"), (_bad_rows, "valid")],
)
def test_bad_model_files(small_model: IMSGenerator, tmp_path: Path, damage, fragment) -> None:
    path = tmp_path / "m.npz"
    small_model.save(path)
    damage(path)
    with pytest.raises(InputError, match=fragment) as error:
        IMSGenerator.load(path)
    assert "\n" not in str(error.value) and "m.npz" in str(error.value)


def test_too_few_frames_and_unfitted() -> None:
    with pytest.raises(InputError, match="not fitted"):
        IMSGenerator().sample_velocity(100)
    with pytest.raises(InputError, match="no trials"):
        IMSGenerator().fit([])


@pytest.mark.long
def test_generated_motion_has_its_person_signature(zhai_trials_100hz: list) -> None:
    """Bundled data, 2/3 of each style for training: the must-show numbers of the generator."""
    rng = np.random.default_rng(0)
    styles = {g: [t for t in zhai_trials_100hz if t.group == g] for g in ("fast", "slow")}
    held_out, generated = {}, {}
    for style, trials in styles.items():
        order = rng.permutation(len(trials))
        train, held_out[style] = [trials[i] for i in order[:6]], [trials[i] for i in order[6:]]
        model = IMSGenerator(random_state=0).fit(train)
        generated[style] = model.sample(60.0, n=3, random_state=1)
    ims = {s: [compute_ims(t.velocity()) for t in held_out[s]] for s in styles}
    every = {s: [compute_ims(t.velocity()) for t in styles[s]] for s in styles}
    human_within = {
        s: np.mean([compute_emd(a, b) for i, a in enumerate(every[s]) for b in every[s][i + 1 :]])
        for s in styles
    }
    between = np.mean([compute_emd(a, b) for a in every["fast"] for b in every["slow"]])
    for style in styles:
        gen_ims = [compute_ims(t.velocity()) for t in generated[style]]
        to_own = np.mean([compute_emd(g, h) for g in gen_ims for h in ims[style]])
        assert to_own <= 1.5 * human_within[style]
        assert to_own <= between / 2
        for g in gen_ims:
            nearest = min(styles, key=lambda s: np.mean([compute_emd(g, h) for h in ims[s]]))
            assert nearest == style
        human = np.vstack([stroke_moments(t.velocity()) for t in styles[style]])
        synthetic = np.vstack([stroke_moments(t.velocity()) for t in generated[style]])
        assert np.all(np.abs(synthetic.mean(axis=0) - human.mean(axis=0)) <= human.std(axis=0))


def test_codebook_sweep_distortion_falls_with_size(zhai_trials_100hz: list) -> None:
    train, test = zhai_trials_100hz[9:11], zhai_trials_100hz[11:12]
    make = IMSGenerator(random_state=0).with_symbols
    sweep = sweep_codebook(make, train, test, sizes=(8, 32), random_state=0, duration=20.0)
    assert list(sweep.index) == [8, 32]
    assert sweep.loc[32, "train_distortion"] < sweep.loc[8, "train_distortion"]
    assert sweep.loc[32, "test_distortion"] < sweep.loc[8, "test_distortion"]
    assert np.all(sweep["test_log_likelihood"] < 0)
    assert np.all((sweep["emd_to_test"] > 0) & (sweep["emd_to_test"] < 0.1))
    # the share of code vectors the held-out frames are nearest to, counted by scikit-learn
    for size in (8, 32):
        model = IMSGenerator(n_symbols=size, random_state=0).fit(train)
        assert model.training_summary_["symbols_used"] == 1.0  # k-means leaves none unused
        frames = np.vstack([model.frame_features(t) for t in test])
        nearest = pairwise_distances_argmin(frames, model.codebook_)
        expected = np.unique(nearest).size / size
        assert sweep.loc[size, "test_symbols_used"] == pytest.approx(expected)
    assert sweep.loc[32, "test_symbols_used"] < 1.0
    with pytest.raises(InputError, match="held-out"):
        sweep_codebook(make, train, [], sizes=(8,))


@pytest.mark.parametrize("n_samples", [6000, 37, 16, 5])
def test_fast_velocity_equals_compute_velocity(small_model: IMSGenerator, n_samples: int) -> None:
    fast = small_model.sample_velocity(n_samples, random_state=4)
    positions = small_model.sample_positions(n_samples, random_state=4)
    np.testing.assert_allclose(fast, compute_velocity(positions, 100.0), rtol=0, atol=1e-12)


def test_velocities_drawn_together_are_each_drawn_alone(small_model: IMSGenerator) -> None:
    seeds = list(range(11))
    together = small_model.sample_velocities(3000, seeds)
    assert together.shape == (11, 3000)
    for seed, velocity in zip(seeds, together, strict=True):
        np.testing.assert_array_equal(velocity, small_model.sample_velocity(3000, seed))


def test_filtering_signals_side_by_side_is_filtering_each(rng: np.random.Generator) -> None:
    signals = np.cumsum(rng.normal(size=(400, 5)), axis=0)
    together = compute_velocity(signals, 100.0)
    for column in range(5):
        np.testing.assert_array_equal(
            together[:, column], compute_velocity(signals[:, column], 100.0)
        )


def test_zero_phase_filter_matches_scipy(rng: np.random.Generator) -> None:
    sos = butter(4, 7.0, fs=100.0, output="sos")
    signal = np.cumsum(rng.normal(size=500))
    for padlen in (0, 15, 40):
        ours = zero_phase_filter(sos, sosfilt_zi(sos), signal, padlen)
        np.testing.assert_allclose(ours, sosfiltfilt(sos, signal, padlen=padlen), atol=1e-12)


def test_a_read_only_signal_is_filtered_by_the_one_compiled_kernel(
    rng: np.random.Generator,
) -> None:
    """A file's columns read without a copy are read-only; they need no second compilation."""
    sos = butter(4, 7.0, fs=100.0, output="sos")
    signal = np.cumsum(rng.normal(size=(500, 2)), axis=0)
    read_only = signal.copy()
    read_only.flags.writeable = False
    ours = zero_phase_filter(sos, sosfilt_zi(sos), read_only, 15)
    np.testing.assert_array_equal(ours, zero_phase_filter(sos, sosfilt_zi(sos), signal, 15))
    np.testing.assert_allclose(ours, sosfiltfilt(sos, signal, axis=0, padlen=15), atol=1e-12)
    assert len(_zero_phase_columns.signatures) == 1


def test_low_rate_model_skips_the_filter(zhai_trials: list) -> None:
    model = IMSGenerator(n_symbols=8, window=8, hop=2, rate=15.0, random_state=0)
    model.fit(zhai_trials[:2])
    positions = model.sample_positions(200, random_state=2)
    np.testing.assert_allclose(
        model.sample_velocity(200, random_state=2), compute_velocity(positions, 15.0), atol=1e-12
    )


def test_a_codebook_needs_frames_for_every_symbol(zhai_trials_100hz) -> None:
    with pytest.raises(InputError, match=r"too few for 256 symbols .* give --symbols 99 or fewer"):
        IMSGenerator(n_symbols=256).fit(zhai_trials_100hz[:1])


def sine_trials(n: int, frequency: float = 0.5) -> list:
    """Solo trials of a pure sine (60 s at 100 Hz, random phases): one stroke shape only."""
    rng = np.random.default_rng(3)
    times = np.arange(6001) / 100.0
    return [
        make_trial(times, 0.3 * np.sin(2 * np.pi * frequency * times + rng.uniform(0, 6.3)))
        for _ in range(n)
    ]


def test_the_one_standard_error_rule_prefers_the_simplest_close_model() -> None:
    """Hand-made scores: the best mean is model 2 (0.10, SE 0.02); model 1 (0.11) lies within
    one SE of it, model 0 (0.20) does not."""
    scores = np.array([[0.18, 0.22], [0.10, 0.12], [0.08, 0.12], [0.13, 0.13]])
    assert one_standard_error_rule(scores) == 1
    assert one_standard_error_rule(scores[[0, 2, 3]]) == 1
    assert one_standard_error_rule(np.array([[0.3, 0.3], [0.1, 0.1]])) == 1


def test_auto_never_asks_for_more_symbols_than_distinct_frames() -> None:
    """A pure sine repeats its frames exactly (40 distinct per trial): sizes above the
    distinct frames of a fold are not tried, so k-means never runs out of points."""
    model = IMSGenerator(random_state=0).fit(sine_trials(4))
    complexity = model.training_summary_["complexity"]
    assert complexity["rule"] == "cross-validation, one standard error"
    assert complexity["folds"] == 4 and complexity["candidates"] == [8, 16, 32, 64]
    assert model.n_symbols_ == complexity["chosen"] == model.codebook_.shape[0]
    assert len(complexity["emd_mean"]) == len(complexity["emd_se"]) == 4


def test_auto_tries_only_sizes_every_fold_can_fit(zhai_trials_100hz) -> None:
    """Two 60 s trials: each fold trains on one trial (about 400 frames, so at most 99
    symbols); one trial alone is split into halves."""
    two = choose_n_symbols(zhai_trials_100hz[:2], IMSGenerator(random_state=0).with_symbols)
    assert two["candidates"] == [8, 16, 32, 64] and two["folds"] == 2
    assert two["human_emd"] == pytest.approx(
        compute_emd(*(compute_ims(t.velocity()) for t in zhai_trials_100hz[:2])), abs=1e-6
    )
    one = choose_n_symbols(zhai_trials_100hz[:1], IMSGenerator(random_state=0).with_symbols)
    assert one["candidates"] == [8, 16, 32] and one["folds"] == 2
    assert np.isnan(one["human_emd"])


def test_auto_is_reproducible_and_saved_with_its_choice(zhai_trials_100hz, tmp_path) -> None:
    trials = zhai_trials_100hz[9:12]
    first = IMSGenerator(random_state=5).fit(trials)
    again = IMSGenerator(random_state=5).fit(trials)
    assert first.training_summary_["complexity"] == again.training_summary_["complexity"]
    np.testing.assert_array_equal(first.codebook_, again.codebook_)
    first.save(tmp_path / "m.npz")
    loaded = IMSGenerator.load(tmp_path / "m.npz")
    assert loaded.n_symbols == loaded.n_symbols_ == first.n_symbols_
    assert loaded.training_summary_["complexity"]["chosen"] == first.n_symbols_
    np.testing.assert_array_equal(loaded.sample_positions(500, 1), first.sample_positions(500, 1))


def test_a_fixed_size_is_still_available(zhai_trials_100hz) -> None:
    model = IMSGenerator(n_symbols=PAPER_SYMBOLS, random_state=0).fit(zhai_trials_100hz[:6])
    assert model.n_symbols_ == 256
    assert model.training_summary_["complexity"] == {"rule": "fixed", "chosen": 256}


def test_exemplars_are_chosen_as_worked_by_hand() -> None:
    """Frames 0-4 with symbols 1 0 1 1 3, frame 4 the last of its trial; symbol 2 has no frame
    (its code vector, index 5 + 2, stands for it). The walk continues a trial only where the
    next frame carries the chain's next symbol."""
    symbols = np.array([1, 0, 1, 1, 3])
    starts, members = group_members(symbols, 4, 5)
    np.testing.assert_array_equal(starts, [0, 1, 4, 5, 6])
    np.testing.assert_array_equal(members, [1, 0, 2, 3, 7, 4])
    chosen = emit_exemplars(
        np.array([1, 1, 0, 2, 3, 1, 1]),
        np.array([0.1, 0.9, 0.5, 0.5, 0.5, 0.4, 0.0]),
        starts,
        members,
        np.array([1, 2, 3, 4, -1]),
        symbols,
    )
    # 1: member 0.1 * 3 -> frame 0; 1: frame 0's successor 1 has symbol 0, so draw 0.9 -> 3;
    # 0: successor 4 has symbol 3, draw -> 1; 2: successor 2 has symbol 1, draw -> 7;
    # 3: a code vector has no successor, draw -> 4; 1: frame 4 ends its trial, draw 0.4 -> 2;
    # 1: frame 2's successor 3 has symbol 1 -> 3 (the trial continues)
    np.testing.assert_array_equal(chosen, [0, 3, 1, 7, 4, 2, 3])


def test_exemplar_emission_keeps_the_persons_speed_that_code_vectors_shrink(
    zhai_trials_100hz: list,
) -> None:
    """Code vectors average their frames: generated motion of the slow bundled style was 14 %
    slower (velocity SD) and its fastest 1 % 27 % slower than the training trials; the
    training frames themselves keep both within 10 % (METHODS section 4, "Fidelity")."""
    train = zhai_trials_100hz[9:14]
    human = np.concatenate([t.velocity() for t in train])
    ratios = {}
    for emission in ("exemplar", "centroid"):
        model = IMSGenerator(32, random_state=0, emission=emission).fit(train)
        generated = model.sample_velocities(6001, [1, 2, 3, 4, 5])
        ratios[emission] = (
            generated.std() / human.std(),
            np.quantile(np.abs(generated), 0.99) / np.quantile(np.abs(human), 0.99),
        )
    assert all(0.9 < r < 1.1 for r in ratios["exemplar"])
    assert ratios["centroid"][0] < 0.9 and ratios["centroid"][1] < 0.8


def test_a_file_from_before_emission_loads_as_code_vectors(
    zhai_trials_100hz: list, tmp_path: Path
) -> None:
    model = IMSGenerator(16, random_state=0, emission="centroid").fit(zhai_trials_100hz[9:11])
    arrays, metadata = model.to_arrays()
    del metadata["parameters"]["emission"]
    save_model(tmp_path / "old.npz", FORMAT_NAME, FORMAT_VERSION, arrays, metadata)
    loaded = IMSGenerator.load(tmp_path / "old.npz")
    assert loaded.emission == "centroid"
    np.testing.assert_array_equal(loaded.sample_velocity(500, 3), model.sample_velocity(500, 3))


def test_exemplar_frames_round_trip_through_a_file(small_model: IMSGenerator, tmp_path) -> None:
    assert small_model.emission == "exemplar"
    small_model.save(tmp_path / "m.npz")
    loaded = IMSGenerator.load(tmp_path / "m.npz")
    np.testing.assert_array_equal(loaded.exemplars_, small_model.exemplars_)
    np.testing.assert_array_equal(loaded.exemplar_next_, small_model.exemplar_next_)
    # one trial's frames follow each other, and each trial's last frame has no successor
    ends = np.flatnonzero(small_model.exemplar_next_ < 0)
    assert ends.size == 3 and ends[-1] == len(small_model.exemplars_) - 1
