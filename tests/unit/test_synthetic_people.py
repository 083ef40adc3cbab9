"""Synthetic people: their trials show the truth they were generated with.

Tolerances are stated in each test; each was set at about three standard errors of its estimate
or more (checked over several seeds), except where a bias is known and named (the truncation of
stroke amplitudes near the ends of the range).
"""

import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.signal

from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets.synthetic import (
    DEVELOPMENT_PEOPLE,
    FRESH_PEOPLE,
    LEAP_RATE,
    SYNTHETIC_PEOPLE,
    TEST_PEOPLE,
    DropOuts,
    Strokes,
    SyntheticPerson,
    Tremor,
    Wander,
)
from mirror_avatar.files.trials import PLAYING_RANGE


def named(kind):
    return [name for name, person in SYNTHETIC_PEOPLE.items() if person.kind == kind]


def bare(name):
    """The person's motion alone: no tremor, no drop-outs (the same motion, see `trials`)."""
    return replace(SYNTHETIC_PEOPLE[name], tremor=None, dropouts=None)


def measured_strokes(trial):
    """Amplitude (units) and duration (s) of each complete run of same-signed steps.

    Exact for a motion without tremor or drop-outs: a stroke is a run of steps of one sign, a
    dwell a run of zero steps; the first and last runs (cut by the trial's ends) are left out.
    """
    steps = np.sign(np.diff(trial.positions))
    edges = np.flatnonzero(np.diff(np.concatenate([[0.0], steps, [0.0]])) != 0)
    amplitudes, durations = [], []
    for start, stop in zip(edges[:-1], edges[1:], strict=True):
        if steps[start] != 0:
            amplitudes.append(abs(trial.positions[stop] - trial.positions[start]))
            durations.append((stop - start) / trial.rate)
    return np.array(amplitudes[1:-1]), np.array(durations[1:-1])


def pooled_strokes(person, n=20):
    found = [measured_strokes(trial) for trial in person.trials(n, seed=3)]
    return np.concatenate([a for a, _ in found]), np.concatenate([d for _, d in found])


def test_strokes_recover_the_set_lognormals_when_the_range_does_not_truncate():
    # Amplitudes of 0.1 units rarely meet the range's ends: medians within 5 % (durations: 5 %
    # plus one sample), log-SDs within 10 %, over 20 one-minute trials (~1000 strokes).
    for rate in (100.0, LEAP_RATE):
        motion = Strokes(0.1, 0.3, 0.6, 0.3, correlation=0.5, dwell=0.1)
        amplitudes, durations = pooled_strokes(SyntheticPerson("probe", "", motion, rate=rate))
        assert amplitudes.size > 500
        assert np.median(amplitudes) == pytest.approx(0.1, rel=0.05)
        assert np.std(np.log(amplitudes)) == pytest.approx(0.3, rel=0.1)
        assert abs(np.median(durations) - 0.6) <= 0.05 * 0.6 + 1 / rate
        assert np.std(np.log(durations)) == pytest.approx(0.3, rel=0.1)
        assert np.corrcoef(np.log(amplitudes), np.log(durations))[0, 1] == pytest.approx(
            0.5, abs=0.1
        )


@pytest.mark.parametrize("name", named("strokes"))
def test_registry_strokes_lie_near_their_set_medians(name):
    # Truncation at the range's ends only shortens strokes (and, by the correlation, their
    # durations): measured medians within [0.8, 1.05] of the set amplitude and [0.85, 1.05] of
    # the set duration (plus one sample).
    motion = SYNTHETIC_PEOPLE[name].motion
    assert isinstance(motion, Strokes)
    rate = SYNTHETIC_PEOPLE[name].rate
    amplitudes, durations = pooled_strokes(bare(name))
    assert 0.8 <= np.median(amplitudes) / motion.amplitude <= 1.05
    assert 0.85 * motion.duration - 1 / rate <= np.median(durations)
    assert np.median(durations) <= 1.05 * motion.duration + 1 / rate
    assert np.all(np.abs(bare(name).trials(5)[0].positions) <= motion.reach + 1e-12)


def test_dwells_are_still_and_have_the_set_mean():
    # ada dwells 0.15 s on average: the mean run of zero steps between strokes within 10 % + a
    # sample (a dwell shorter than a step can vanish, one longer is cut to whole samples).
    person = bare("ada")
    durations = []
    for trial in person.trials(10, seed=1):
        still = np.diff(trial.positions) == 0
        edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(int), [0]])))
        durations.extend((edges[1::2] - edges[0::2])[1:-1] / trial.rate)
    assert np.mean(durations) == pytest.approx(person.motion.dwell, abs=0.1 * 0.15 + 0.01)
    no_dwell = bare("dmitri").trials(1)[0]
    assert np.count_nonzero(np.diff(no_dwell.positions) == 0) == 0


@pytest.mark.parametrize("name", named("oscillator"))
def test_oscillator_peaks_at_its_frequency_with_its_spread(name):
    # The mean Welch spectrum of the position (20 s segments, 0.05 Hz bins) over 10 trials peaks
    # within one bin of the set frequency; the position's RMS is within 5 % of
    # sqrt((amplitude^2 + amplitude_sd^2) / 2).
    person = bare(name)
    motion = person.motion
    positions = np.stack([trial.positions for trial in person.trials(10)])
    frequencies, power = scipy.signal.welch(
        positions, fs=person.rate, nperseg=round(20 * person.rate)
    )
    peak = frequencies[np.argmax(power.mean(axis=0))]
    assert abs(peak - motion.frequency) <= 0.05 + 1e-9
    expected = math.sqrt((motion.amplitude**2 + motion.amplitude_sd**2) / 2)
    assert math.sqrt(np.mean(positions**2)) == pytest.approx(expected, rel=0.05)


@pytest.mark.parametrize("name", named("wander"))
def test_wander_has_its_position_sd_and_corner(name):
    # Over 40 one-minute trials: the RMS position (mean known, 0) within 10 % of the set SD;
    # the corner from the velocity-to-position ratio of a Butterworth spectrum,
    # sd(v) / (2 pi sd(x)) * sqrt(sin(3 pi / 2n) / sin(pi / 2n)), within 10 % of the set one.
    person = bare(name)
    motion = person.motion
    trials = person.trials(40, seed=2)
    position_sd = math.sqrt(np.mean(np.concatenate([t.positions for t in trials]) ** 2))
    velocity_sd = math.sqrt(
        np.mean(np.concatenate([np.diff(t.positions) * t.rate for t in trials]) ** 2)
    )
    order = motion.order
    shape = math.sqrt(math.sin(3 * math.pi / (2 * order)) / math.sin(math.pi / (2 * order)))
    corner = velocity_sd / (2 * math.pi * position_sd) * shape
    assert position_sd == pytest.approx(motion.sd, rel=0.1)
    assert corner == pytest.approx(motion.corner, rel=0.1)


@pytest.mark.parametrize("name", [n for n, p in SYNTHETIC_PEOPLE.items() if p.tremor])
def test_tremor_has_its_band_and_amplitude(name):
    # Welch spectrum (2 s Hann segments) over 5 trials: the RMS in the tremor's band within 5 %
    # of the set amplitude; the motion without tremor has under a third of it there.
    person = replace(SYNTHETIC_PEOPLE[name], dropouts=None)
    tremor = person.tremor
    assert tremor is not None

    def band_rms(p):
        positions = np.stack([trial.positions for trial in p.trials(5)])
        frequencies, power = scipy.signal.welch(positions, fs=p.rate, nperseg=round(2 * p.rate))
        inside = (frequencies >= tremor.low) & (frequencies <= tremor.high)
        return math.sqrt(power.mean(axis=0)[inside].sum() * frequencies[1])

    assert band_rms(person) == pytest.approx(tremor.amplitude, rel=0.05)
    assert band_rms(replace(person, tremor=None)) < tremor.amplitude / 3


def held_time_sd(dropouts, seconds):
    """SD (s) of the held time over ``seconds`` of an alternating renewal process.

    Exponential phases of means t0 (tracked) and t1 (held): asymptotically the held time has
    variance 2 t0^2 t1^2 / (t0 + t1)^3 per second.
    """
    tracked, held = 1 / dropouts.rate, dropouts.mean_length
    return math.sqrt(2 * tracked**2 * held**2 / (tracked + held) ** 3 * seconds)


def held_share(trials):
    return np.mean(np.concatenate([np.diff(t.positions) == 0 for t in trials]))


def test_dropouts_hold_the_expected_share_of_samples():
    # Each sample after the first is held with probability p = r L / (1 + r L) (the stationary
    # share of an alternating renewal process with mean phases 1/r and L). On a wander (which
    # never repeats a sample by itself), over 50 one-minute trials: within 4 SD of the held time.
    dropouts = DropOuts(0.2, 0.5)
    person = replace(bare("chloe"), dropouts=dropouts)
    trials = person.trials(50)
    tolerance = 4 * held_time_sd(dropouts, 50 * 60.0) / (50 * 60.0)
    assert dropouts.held_fraction == pytest.approx(0.1 / 1.1)
    assert held_share(trials) == pytest.approx(dropouts.held_fraction, abs=tolerance)
    clean = bare("chloe").trials(50)
    for recorded, motion in zip(trials, clean, strict=True):
        assert recorded.positions[0] == motion.positions[0]
        tracked = np.diff(recorded.positions) != 0
        assert np.array_equal(recorded.positions[1:][tracked], motion.positions[1:][tracked])


@pytest.mark.parametrize(
    "name", [n for n, p in SYNTHETIC_PEOPLE.items() if p.dropouts and p.kind != "strokes"]
)
def test_registry_dropouts_hold_their_share(name):
    # As above, 30 trials, within 4 SD (a stroke person's dwells repeat samples by themselves).
    dropouts = SYNTHETIC_PEOPLE[name].dropouts
    assert dropouts is not None
    tolerance = 4 * held_time_sd(dropouts, 30 * 60.0) / (30 * 60.0)
    share = held_share(SYNTHETIC_PEOPLE[name].trials(30))
    assert share == pytest.approx(dropouts.held_fraction, abs=tolerance)


@pytest.mark.parametrize("name", list(SYNTHETIC_PEOPLE))
def test_trials_are_labelled_in_range_and_uniform(name):
    person = SYNTHETIC_PEOPLE[name]
    trials = person.trials(3, duration=20.0, seed=4)
    assert [t.label for t in trials] == [f"{name}-1", f"{name}-2", f"{name}-3"]
    for k, trial in enumerate(trials, start=1):
        assert trial.group == name
        assert trial.metadata == {
            "dataset": "synthetic",
            "kind": person.kind,
            "seed": 4,
            "trial": k,
        }
        assert trial.is_uniform
        assert trial.times[0] == 0.0
        assert trial.rate == pytest.approx(person.rate)
        assert trial.n_samples == math.floor(20.0 * person.rate + 1e-9) + 1
        assert (
            PLAYING_RANGE[0] <= trial.positions.min() <= trial.positions.max() <= PLAYING_RANGE[1]
        )
        assert trial.positions.std() > 0.03


def test_same_seed_same_trials_and_trial_k_independent_of_n():
    person = SYNTHETIC_PEOPLE["elena"]
    three, five = person.trials(3, seed=7), person.trials(5, seed=7)
    for a, b in zip(three, five[:3], strict=True):
        assert np.array_equal(a.positions, b.positions)
        assert np.array_equal(a.times, b.times)
    assert not np.array_equal(five[0].positions, five[1].positions)
    assert not np.array_equal(three[0].positions, person.trials(1, seed=8)[0].positions)


def test_people_with_the_same_parameters_but_other_names_move_differently():
    twin = replace(SYNTHETIC_PEOPLE["chloe"], name="chloe2")
    assert not np.array_equal(
        twin.trials(1)[0].positions, SYNTHETIC_PEOPLE["chloe"].trials(1)[0].positions
    )


def test_tremor_adds_to_an_unchanged_motion():
    # The tremor draws from its own stream: removing it leaves the motion as it was, and the
    # difference is the tremor, of RMS the set amplitude (up to the clipping, 2 %).
    person = SYNTHETIC_PEOPLE["ines"]
    assert person.tremor is not None
    with_tremor = person.trials(2, seed=1)
    motion = bare("ines").trials(2, seed=1)
    for a, b in zip(with_tremor, motion, strict=True):
        assert np.sqrt(np.mean((a.positions - b.positions) ** 2)) == pytest.approx(
            person.tremor.amplitude, rel=0.02
        )


def test_registry_splits_into_disjoint_development_test_and_fresh_people():
    sets = (DEVELOPMENT_PEOPLE, TEST_PEOPLE, FRESH_PEOPLE)
    assert sum(len(names) for names in sets) == len(set().union(*sets))
    assert set().union(*sets) == set(SYNTHETIC_PEOPLE)
    assert all(person.name == name for name, person in SYNTHETIC_PEOPLE.items())
    for names in sets:
        people = [SYNTHETIC_PEOPLE[name] for name in names]
        assert {p.kind for p in people} == {"strokes", "oscillator", "wander"}
        assert {round(p.rate) for p in people} == {13, 60, 100}
        assert any(p.tremor for p in people) and any(p.dropouts for p in people)
        assert all(p.description for p in people)


def test_impossible_people_are_refused():
    with pytest.raises(InputError, match="Tremor.high"):
        SyntheticPerson("x", "", Wander(0.1, 0.1), rate=LEAP_RATE, tremor=Tremor(0.002))
    with pytest.raises(InputError, match="Wander.sd"):
        Wander(0.1, 0.3)
    with pytest.raises(InputError, match="Strokes.amplitude"):
        Strokes(1.0, 0.3, 0.5, 0.3)
    with pytest.raises(InputError, match="seed"):
        SYNTHETIC_PEOPLE["ada"].trials(1, seed=-1)
