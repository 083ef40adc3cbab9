"""The stroke generator (`mirror_avatar.motion.strokes`): strokes, chaining, files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.signal
import scipy.stats

from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.files.trials import compute_velocity, make_trial
from mirror_avatar.motion.models import load_motion, model_arrays, motion_from_arrays
from mirror_avatar.motion.strokes import (
    StrokeGenerator,
    reversals,
    room_ahead,
    silverman_bandwidth,
)

RATE = 100.0


def sine_trial(seconds: float = 30.0, frequency: float = 0.5, amplitude: float = 0.3):
    times = np.arange(round(seconds * RATE) + 1) / RATE
    positions = amplitude * np.sin(2 * np.pi * frequency * times)
    return make_trial(times, positions, label="sine", group="sine")


def test_reversals_are_the_turning_points_and_a_pause_keeps_its_stroke() -> None:
    positions = np.array([0.0, 1, 2, 2, 2, 3, 2, 1, 1, 0, 1])
    assert reversals(positions).tolist() == [0, 5, 9, 10]
    assert reversals(np.zeros(5)).tolist() == [0, 4]
    held = np.array([0.0, 1, 3, 3, 2, 0])
    assert reversals(held).tolist() == [0, 3, 5]


def test_a_small_turn_back_is_not_a_reversal() -> None:
    """Tremor of 0.004 units on a ramp up and down: one turn at the top, none in the wiggles."""
    ramp = np.concatenate([np.linspace(-0.3, 0.3, 301), np.linspace(0.3, -0.3, 301)[1:]])
    wiggles = 0.004 * np.sin(2 * np.pi * np.arange(ramp.size) / 11)
    assert reversals(ramp + wiggles, 0.01).tolist()[0] == 0
    assert len(reversals(ramp + wiggles, 0.01)) == 3
    assert abs(reversals(ramp + wiggles, 0.01)[1] - 300) <= 6
    assert len(reversals(ramp + wiggles, 0.0)) > 50


def test_room_ahead_is_the_distance_to_the_edge_moved_towards() -> None:
    assert room_ahead(0.2, 1.0) == pytest.approx(0.3)
    assert room_ahead(0.2, -1.0) == pytest.approx(0.7)


def test_a_periodic_person_without_jitter_is_played_back_periodic() -> None:
    """One neighbour, no jitter, one sine: every stroke is the sine's half period (truth)."""
    model = StrokeGenerator(neighbours=1, jitter=0.0, random_state=3).fit([sine_trial()])
    positions = model.sample_positions(3001)
    edges = reversals(positions)[1:-1]
    assert np.diff(edges) == pytest.approx(np.full(edges.size - 1, 100.0), abs=1)
    assert np.abs(positions[edges]) == pytest.approx(np.full(edges.size, 0.3), abs=1e-3)


def test_generated_strokes_have_the_training_strokes_lengths_and_sizes() -> None:
    """Medians of generated stroke lengths and sizes within 10 % of the training trials'.

    Strokes of the generated motion cut as the fit cuts them.
    """
    trials = [t for t in load_zhai2017() if t.group == "fast"]
    model = StrokeGenerator(random_state=0).fit(trials)
    trained_lengths, trained_sizes = model.lengths_, np.abs(model.displacements_)
    lengths, sizes = [], []
    for seed in range(5):
        positions = model.sample_positions(6001, seed)
        edges = reversals(positions, model.min_reversal)[1:-1]
        lengths.append(np.diff(edges))
        sizes.append(np.abs(np.diff(positions[edges])))
    assert np.median(np.concatenate(lengths)) == pytest.approx(np.median(trained_lengths), rel=0.1)
    assert np.median(np.concatenate(sizes)) == pytest.approx(np.median(trained_sizes), rel=0.1)


def test_generated_motion_has_no_ripple_the_person_does_not_make() -> None:
    """The 2-8 Hz share of velocity power within 1.5 x the training trials' (slow style)."""
    trials = [t for t in load_zhai2017() if t.group == "slow"]
    model = StrokeGenerator(random_state=0).fit(trials)

    def ripple(velocity: np.ndarray) -> float:
        frequencies, power = scipy.signal.welch(velocity, fs=RATE, nperseg=1000)
        return power[(frequencies >= 2) & (frequencies <= 8)].sum() / power.sum()

    person = np.mean([ripple(t.resampled(RATE).velocity()) for t in trials])
    generated = np.mean([ripple(v) for v in model.sample_velocities(6001, list(range(5)))])
    assert generated < 1.5 * person


def test_samples_stay_in_range_and_repeat_with_their_seed() -> None:
    model = StrokeGenerator(random_state=1).fit([sine_trial(amplitude=0.5)])
    first = model.sample_positions(2000, 7)
    assert np.all(np.abs(first) <= 0.5)
    assert np.array_equal(first, model.sample_positions(2000, 7))
    velocities = model.sample_velocities(500, [4, 5])
    assert np.array_equal(velocities[1], model.sample_velocity(500, 5))
    assert np.array_equal(velocities[0], compute_velocity(model.sample_positions(500, 4), RATE))


def drawable_strokes(trials, rate: float = RATE, min_reversal: float = 0.01) -> list[dict]:
    """Each stroke with one before and one after it in its trial, cut as the fit cuts them."""
    strokes = []
    for trial in trials:
        positions = trial.resampled(rate).positions
        edges = reversals(positions, min_reversal)
        for i in range(1, edges.size - 2):
            first, last = edges[i], edges[i + 1]
            strokes.append(
                {
                    "length": float(last - first),
                    "displacement": positions[last] - positions[first],
                    "start": positions[first],
                    "before_length": float(first - edges[i - 1]),
                    "before_size": abs(positions[first] - positions[edges[i - 1]]),
                }
            )
    return strokes


def test_the_fit_keeps_each_drawable_stroke_with_its_predecessor() -> None:
    trials = [t for t in load_zhai2017() if t.group == "slow"][:3]
    model = StrokeGenerator(random_state=0).fit(trials)
    strokes = drawable_strokes(trials)
    for key, values in [
        ("length", model.lengths_), ("displacement", model.displacements_),
        ("start", model.starts_), ("before_length", model.before_lengths_),
        ("before_size", model.before_sizes_),
    ]:  # fmt: skip
        assert values == pytest.approx([stroke[key] for stroke in strokes], abs=1e-12), key


def test_the_next_stroke_is_drawn_from_the_nearest_neighbours() -> None:
    """With one neighbour the draw is the nearest by a brute-force search over the strokes cut
    from the trials."""
    trials = [t for t in load_zhai2017() if t.group == "slow"][:3]
    model = StrokeGenerator(neighbours=1, random_state=0).fit(trials)
    strokes = drawable_strokes(trials)
    features = np.array(
        [[np.log(s["before_length"]), np.log(s["before_size"] + 1e-4), s["start"]] for s in strokes]
    )
    rng = np.random.default_rng(0)
    for length, size, position, direction in [(40.0, 0.1, 0.0, 1.0), (80.0, 0.3, 0.3, -1.0)]:
        best, best_distance = -1, np.inf
        for i, stroke in enumerate(strokes):
            if np.sign(stroke["displacement"]) != direction:
                continue
            own = features[i].copy()
            own[2] = float(room_ahead(stroke["start"], direction))
            state = np.array(
                [np.log(length), np.log(size + 1e-4), float(room_ahead(position, direction))]
            )
            distance = np.sum(((own - state) / model._scale) ** 2)
            if distance < best_distance:
                best, best_distance = i, distance
        assert model._next_stroke(length, size, position, direction, rng) == best


def test_a_saved_model_loads_and_samples_the_same(tmp_path: Path) -> None:
    model = StrokeGenerator(random_state=2).fit([sine_trial(), sine_trial(frequency=0.7)])
    model.save(tmp_path / "m.npz")
    loaded = load_motion(tmp_path / "m.npz")
    assert isinstance(loaded, StrokeGenerator)
    assert np.array_equal(loaded.sample_positions(999, 1), model.sample_positions(999, 1))
    arrays, metadata = model_arrays(model)
    assert metadata["kind"] == "strokes"
    again = motion_from_arrays(arrays, metadata, "avatar.npz")
    assert np.array_equal(again.sample_positions(99, 1), model.sample_positions(99, 1))


@pytest.mark.parametrize(
    ("name", "change", "words"),
    [
        ("before_sizes", lambda a: a.__setitem__(0, -1.0), "before_sizes"),
        ("bandwidth", lambda a: a.__setitem__(0, np.inf), "bandwidth"),
        ("lengths", lambda a: a.__setitem__(0, 2.5), "whole numbers"),
        ("profiles", lambda a: a.__setitem__(0, np.nan), "profiles"),
    ],
)
def test_a_tampered_model_is_refused_naming_the_file(name, change, words) -> None:
    model = StrokeGenerator(random_state=2).fit([sine_trial()])
    arrays, metadata = model.to_arrays()
    arrays = {key: value.copy() for key, value in arrays.items()}
    change(arrays[name])
    with pytest.raises(InputError, match=words) as raised:
        StrokeGenerator.from_arrays(arrays, metadata, "person.npz")
    assert "person.npz" in str(raised.value)


def test_profiles_of_another_size_are_refused() -> None:
    arrays, metadata = StrokeGenerator(random_state=2).fit([sine_trial()]).to_arrays()
    with pytest.raises(InputError, match="profiles"):
        StrokeGenerator.from_arrays(arrays | {"profiles": arrays["profiles"][:-1]}, metadata, "m")


def test_too_few_strokes_are_refused_with_what_to_do() -> None:
    with pytest.raises(InputError, match="longer trials or more"):
        StrokeGenerator().fit([sine_trial(seconds=1.5)])


def test_an_unknown_kind_is_refused() -> None:
    arrays, metadata = model_arrays(StrokeGenerator(random_state=2).fit([sine_trial()]))
    with pytest.raises(InputError, match="unknown motion model kind"):
        motion_from_arrays(arrays, metadata | {"kind": "lstm"}, "m.npz")


def test_the_jitter_bandwidth_is_silvermans_rule_as_scipy_computes_it() -> None:
    """1.06 SD m^(-1/5) against scipy's gaussian_kde Silverman factor (d = 1), within 0.2 %."""
    samples = np.random.default_rng(0).normal(size=(5000, 1)) * 0.3
    kde = scipy.stats.gaussian_kde(samples[:, 0], bw_method="silverman")
    expected = kde.factor * samples[:, 0].std(ddof=1)
    assert silverman_bandwidth(samples)[0] == pytest.approx(expected, rel=2e-3)


def test_a_regular_person_gets_less_jitter_than_an_irregular_one() -> None:
    regular = StrokeGenerator().fit([sine_trial(60.0)])
    irregular = StrokeGenerator().fit([t for t in load_zhai2017() if t.group == "slow"])
    assert np.all(regular.bandwidth_ < 1e-6)
    assert np.all(irregular.bandwidth_ > 0.05)


def test_arrays_that_link_each_stroke_to_the_one_before_are_read_as_the_fit_keeps_them() -> None:
    """Model arrays written with every training stroke and its ``previous`` (avatar files made
    before the predecessors' features were kept) sample as the model fitted now does."""
    trials = [t for t in load_zhai2017() if t.group == "slow"][:3]
    model = StrokeGenerator(random_state=0).fit(trials)
    lengths, displacements, starts, previous, profiles = [], [], [], [], []
    for trial in trials:
        positions = trial.resampled(RATE).positions
        edges = reversals(positions, 0.01)
        for number, (first, last) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
            previous.append(len(lengths) - 1 if number else -1)
            lengths.append(float(last - first))
            displacements.append(positions[last] - positions[first])
            starts.append(positions[first])
            profiles.append((positions[first : last + 1] - positions[first]) / displacements[-1])
    arrays = {
        "lengths": np.array(lengths), "displacements": np.array(displacements),
        "starts": np.array(starts), "previous": np.array(previous),
        "profiles": np.concatenate(profiles),
    }  # fmt: skip
    _, metadata = model.to_arrays()
    legacy = StrokeGenerator.from_arrays(arrays, metadata, "avatar.npz")
    assert np.array_equal(legacy.sample_positions(3000, 5), model.sample_positions(3000, 5))
    arrays["previous"][3] = 3
    with pytest.raises(InputError, match="earlier stroke"):
        StrokeGenerator.from_arrays(arrays, metadata, "avatar.npz")
