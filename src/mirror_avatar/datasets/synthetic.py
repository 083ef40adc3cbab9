"""Synthetic people: solo trials from set generating processes, so the truth is known.

Each `SyntheticPerson` moves by one of three processes (its **kind**), each plausible for a finger
moving sideways, with set parameters (the known truth; METHODS section 3, Synthetic people):

- ``strokes`` (`Strokes`): point-to-point strokes with minimum-jerk profiles, lognormal
  amplitudes and durations, a dwell at each reversal;
- ``oscillator`` (`Oscillation`): a nearly periodic motion whose frequency and amplitude drift
  as Ornstein-Uhlenbeck processes, like the bundled ``fast`` style (about 1 Hz);
- ``wander`` (`Wander`): Gaussian noise low-passed by a Butterworth filter of set order and
  corner frequency, scaled to a set position SD, like the bundled ``slow`` style.

Any person may add a physiological tremor (`Tremor`: narrow-band noise) and tracking drop-outs
(`DropOuts`: runs where the recorded position is held at its last value, as the Leap Motion
recordings show). Positions are clipped to the playing range and sampled uniformly at the
person's recording rate (about 13 Hz like the Leap Motion tracker, 60 Hz or 100 Hz).

Protocol: methods of making motion (generators, avatars) are developed on these people and
judged on others held out. `DEVELOPMENT_PEOPLE` (``ada``, ``bruno``, ``chloe``, ``dmitri``) are
the only ones any design choice may look at: tuning, model selection, plots, thresholds.
`TEST_PEOPLE` (``elena`` to ``jonas``) are held out of every choice: do not generate, plot or
measure them while choosing a method, only to report the chosen method's result. A held-out set
whose results have been seen once informs the next choice however careful one is, so each round
of choices is judged on people no result was seen of: `FRESH_PEOPLE` (``kofi`` to ``nora``) are
the next round's. Every set covers the three kinds and the three rates, with and without dwell,
tremor and drop-outs.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, lfilter, sosfilt
from scipy.special import ndtr, ndtri

from mirror_avatar.common.constraints import Interval, check
from mirror_avatar.files.trials import DEFAULT_RATE, PLAYING_RANGE, Trial, make_trial

Array = NDArray[np.float64]

Kind = Literal["strokes", "oscillator", "wander"]
"""The generating processes."""

LEAP_RATE = 778 / 60
"""Recording rate (Hz) of the bundled Leap Motion trials: 779 samples over 60 s, about 13 Hz."""

WARM_UP = 10.0
"""Seconds a stroke sequence runs before a trial starts, so that its start is not special."""

BURN_IN_CYCLES = 20.0
"""A wander's filter runs this many corner periods before a trial starts (its transient is then
below e^-20 of the stationary SD)."""


def _positive(owner: str, name: str, value: float, high: float | None = None) -> None:
    check(
        f"{owner}.{name}", value, Interval(float, 0.0, high, closed="right" if high else "neither")
    )


def _non_negative(owner: str, name: str, value: float, high: float | None = None) -> None:
    check(f"{owner}.{name}", value, Interval(float, 0.0, high))


def _ornstein_uhlenbeck(
    rng: np.random.Generator, n: int, sd: float, tau: float, step: float
) -> Array:
    """Sample a stationary Ornstein-Uhlenbeck process exactly, shape (n,).

    Mean 0, stationary SD ``sd``, time constant ``tau`` (s), sample spacing ``step`` (s): the
    first sample is drawn from the stationary law, then ``y[k] = a y[k-1] + sd sqrt(1 - a^2) e``
    with ``a = exp(-step / tau)``.
    """
    a = math.exp(-step / tau)
    shocks = sd * math.sqrt(1.0 - a * a) * rng.standard_normal(n)
    shocks[0] = sd * rng.standard_normal()
    return np.asarray(lfilter([1.0], [1.0, -a], shocks))


@dataclass(frozen=True)
class Strokes:
    """Point-to-point strokes, alternating in direction, with minimum-jerk profiles.

    A stroke of amplitude ``A`` and duration ``D`` from ``x0`` follows
    ``x0 +- A (10 s^3 - 15 s^4 + 6 s^5)``, ``s = t / D`` (Flash & Hogan 1985), then the finger
    dwells still before the next stroke, which reverses the direction. The logs of a stroke's
    amplitude and duration are jointly normal; the amplitude's is truncated so that the stroke
    ends inside ``[-reach, reach]`` (the lognormal conditioned on the stroke fitting), so strokes
    that start near an end are shorter than the lognormal alone would make them.

    Parameters
    ----------
    amplitude
        Median stroke amplitude before truncation (units): the distance between two reversals.
    amplitude_log_sd
        SD of the natural log of the amplitude.
    duration
        Median stroke duration (s), the dwell not included.
    duration_log_sd
        SD of the natural log of the duration.
    correlation
        Correlation of the logs of a stroke's amplitude and duration (longer strokes slower).
    dwell
        Mean dwell at each reversal (s), exponentially distributed; 0 for none. A dwell is
        exact stillness (identical samples, as a drop-out gives): give a `Tremor` for a living
        rest.
    reach
        Stroke ends lie in ``[-reach, reach]`` (units).
    """

    amplitude: float
    amplitude_log_sd: float
    duration: float
    duration_log_sd: float
    correlation: float = 0.0
    dwell: float = 0.0
    reach: float = 0.45
    kind: ClassVar[Kind] = "strokes"

    def __post_init__(self) -> None:
        _positive("Strokes", "reach", self.reach, PLAYING_RANGE[1])
        _positive("Strokes", "amplitude", self.amplitude, 2 * self.reach)
        _positive("Strokes", "amplitude_log_sd", self.amplitude_log_sd, 2.0)
        _positive("Strokes", "duration", self.duration, 10.0)
        _positive("Strokes", "duration_log_sd", self.duration_log_sd, 2.0)
        check("Strokes.correlation", self.correlation, Interval(float, -1.0, 1.0))
        _non_negative("Strokes", "dwell", self.dwell, 10.0)

    def positions(self, times: Array, rng: np.random.Generator) -> Array:
        """Positions (units) at ``times`` (s from the trial's start, increasing), shape (n,)."""
        t = -WARM_UP
        x = rng.uniform(-self.reach, self.reach)
        direction = 1.0 if rng.random() < 0.5 else -1.0
        spread = math.sqrt(1.0 - self.correlation**2)
        starts, durations, origins, travels = [], [], [], []
        while t <= times[-1]:
            room = self.reach - direction * x
            z_room = (math.log(room) - math.log(self.amplitude)) / self.amplitude_log_sd
            z_amplitude = float(ndtri(max(rng.random() * float(ndtr(z_room)), 1e-300)))
            z_duration = self.correlation * z_amplitude + spread * rng.standard_normal()
            amplitude = min(self.amplitude * math.exp(self.amplitude_log_sd * z_amplitude), room)
            duration = self.duration * math.exp(self.duration_log_sd * z_duration)
            starts.append(t)
            durations.append(duration)
            origins.append(x)
            travels.append(direction * amplitude)
            t += duration + (rng.exponential(self.dwell) if self.dwell > 0 else 0.0)
            x += direction * amplitude
            direction = -direction
        index = np.searchsorted(starts, times, side="right") - 1
        s = np.clip((times - np.asarray(starts)[index]) / np.asarray(durations)[index], 0.0, 1.0)
        shape = s**3 * (10.0 - 15.0 * s + 6.0 * s * s)
        return np.asarray(origins)[index] + np.asarray(travels)[index] * shape


@dataclass(frozen=True)
class Oscillation:
    """A nearly periodic motion, ``x = A(t) sin(phi(t))``, ``phi' = 2 pi f(t)``.

    The frequency ``f`` and the amplitude ``A`` each drift about their means as independent
    stationary Ornstein-Uhlenbeck processes with one time constant; the frequency is floored at
    0 (the phase never runs back) and the amplitude at 0. The position's SD is
    ``sqrt((amplitude^2 + amplitude_sd^2) / 2)``.

    Parameters
    ----------
    frequency
        Mean frequency (Hz).
    amplitude
        Mean amplitude (units): the peak distance from the centre, 0.
    frequency_sd
        Stationary SD of the frequency's drift (Hz).
    amplitude_sd
        Stationary SD of the amplitude's drift (units).
    time_constant
        Time constant of both drifts (s).
    """

    frequency: float
    amplitude: float
    frequency_sd: float
    amplitude_sd: float
    time_constant: float
    kind: ClassVar[Kind] = "oscillator"

    def __post_init__(self) -> None:
        _positive("Oscillation", "frequency", self.frequency, 5.0)
        _positive("Oscillation", "amplitude", self.amplitude, PLAYING_RANGE[1])
        _non_negative("Oscillation", "frequency_sd", self.frequency_sd, self.frequency / 2)
        _non_negative("Oscillation", "amplitude_sd", self.amplitude_sd, self.amplitude / 2)
        _positive("Oscillation", "time_constant", self.time_constant, 1000.0)

    def positions(self, times: Array, rng: np.random.Generator) -> Array:
        """Positions (units) at uniform ``times`` (s from the trial's start), shape (n,)."""
        step = float(times[1] - times[0])
        n = times.size
        frequency = self.frequency + _ornstein_uhlenbeck(
            rng, n, self.frequency_sd, self.time_constant, step
        )
        amplitude = self.amplitude + _ornstein_uhlenbeck(
            rng, n, self.amplitude_sd, self.time_constant, step
        )
        phase = rng.uniform(0.0, 2 * math.pi) + 2 * math.pi * step * np.cumsum(
            np.maximum(frequency, 0.0)
        )
        return np.maximum(amplitude, 0.0) * np.sin(phase)


@dataclass(frozen=True)
class Wander:
    """Slow wandering: white Gaussian noise through a Butterworth low-pass filter.

    The position's power spectrum is ``S(f) ~ 1 / (1 + (f / corner)^(2 order))`` (the filter is
    designed digitally at the recording rate, bilinear transform), scaled so that the stationary
    SD is ``sd``. Its velocity-to-position SD ratio gives the corner back:
    ``corner = sd(v) / (2 pi sd(x)) * sqrt(sin(3 pi / 2 order) / sin(pi / 2 order))``.

    Parameters
    ----------
    corner
        Corner (half-power) frequency of the position spectrum (Hz).
    sd
        Stationary SD of the position (units).
    order
        Butterworth order, 2 to 4: the position spectrum falls as ``f^(-2 order)`` above the
        corner (order 2 gives a rough velocity, order 4 a smooth one).
    """

    corner: float
    sd: float
    order: int = 2
    kind: ClassVar[Kind] = "wander"

    def __post_init__(self) -> None:
        _positive("Wander", "corner", self.corner, 2.0)
        _positive("Wander", "sd", self.sd, 0.2)
        check("Wander.order", self.order, Interval(int, 2, 4))

    def positions(self, times: Array, rng: np.random.Generator) -> Array:
        """Positions (units) at uniform ``times`` (s from the trial's start), shape (n,)."""
        rate = 1.0 / float(times[1] - times[0])
        sos = butter(self.order, self.corner, btype="low", fs=rate, output="sos")
        burn_in = math.ceil(BURN_IN_CYCLES / self.corner * rate)
        impulse = np.zeros(burn_in)
        impulse[0] = 1.0
        gain = math.sqrt(float(np.sum(sosfilt(sos, impulse) ** 2)))
        filtered = sosfilt(sos, rng.standard_normal(burn_in + times.size))[burn_in:]
        return np.asarray(filtered * (self.sd / gain))


Motion = Strokes | Oscillation | Wander
"""The motion of a person, one of the kinds."""


@dataclass(frozen=True)
class Tremor:
    """Physiological tremor added to the motion: Gaussian noise band-passed to a narrow band.

    The band-passing is done in the Fourier domain (bins outside the band zeroed), and the noise
    is scaled so that its RMS over each trial is exactly ``amplitude``.

    Parameters
    ----------
    amplitude
        RMS of the tremor's displacement (units).
    low, high
        Edges of the band (Hz); ``high`` must lie below the person's Nyquist frequency.
    """

    amplitude: float
    low: float = 8.0
    high: float = 11.0

    def __post_init__(self) -> None:
        _positive("Tremor", "amplitude", self.amplitude, 0.05)
        _positive("Tremor", "low", self.low, 30.0)
        check("Tremor.high", self.high, Interval(float, self.low, 30.0, closed="right"))

    def displacement(self, n: int, rate: float, rng: np.random.Generator) -> Array:
        """Return the tremor over ``n`` samples at ``rate`` Hz (units), shape (n,)."""
        spectrum = np.fft.rfft(rng.standard_normal(n))
        frequencies = np.fft.rfftfreq(n, 1.0 / rate)
        spectrum[(frequencies < self.low) | (frequencies > self.high)] = 0.0
        noise = np.fft.irfft(spectrum, n)
        return np.asarray(noise * (self.amplitude / math.sqrt(np.mean(noise**2))))


@dataclass(frozen=True)
class DropOuts:
    """Tracking losses: runs where the recorded position is held at its last tracked value.

    Tracking and holding alternate, each for an exponentially distributed time: while tracked, a
    loss starts at ``rate`` per second; a loss lasts ``mean_length`` s on average. The process is
    stationary from the trial's start (held at the start with the stationary probability), so each
    sample after the first is held with probability
    ``rate * mean_length / (1 + rate * mean_length)``; the first sample is always tracked.

    Parameters
    ----------
    rate
        Losses per second of tracked time (1/s).
    mean_length
        Mean length of a loss (s).
    """

    rate: float
    mean_length: float

    def __post_init__(self) -> None:
        _positive("DropOuts", "rate", self.rate, 10.0)
        _positive("DropOuts", "mean_length", self.mean_length, 60.0)

    @property
    def held_fraction(self) -> float:
        """Expected share of the samples held (the stationary probability of a loss)."""
        lost = self.rate * self.mean_length
        return lost / (1.0 + lost)

    def held(self, times: Array, rng: np.random.Generator) -> NDArray[np.bool_]:
        """Which samples at ``times`` (s from the trial's start) are held, shape (n,)."""
        held = np.zeros(times.size, dtype=bool)
        lost = rng.random() < self.held_fraction
        t = 0.0
        while t <= times[-1]:
            length = rng.exponential(self.mean_length if lost else 1.0 / self.rate)
            if lost:
                held[(times >= t) & (times < t + length)] = True
            t += length
            lost = not lost
        held[0] = False
        return held


@dataclass(frozen=True)
class SyntheticPerson:
    """A synthetic person: a generating process with known parameters and a recording rate.

    Parameters
    ----------
    name
        The person's name: the group of their trials and the stem of the trials' labels.
    description
        What their motion is like, in a sentence.
    motion
        The generating process and its parameters (the known truth).
    rate
        Recording rate (Hz).
    tremor
        Tremor added to the motion, or None.
    dropouts
        Tracking drop-outs, or None.
    """

    name: str
    description: str
    motion: Motion
    rate: float = DEFAULT_RATE
    tremor: Tremor | None = None
    dropouts: DropOuts | None = None

    def __post_init__(self) -> None:
        _positive("SyntheticPerson", "rate", self.rate, 1000.0)
        if self.tremor is not None:
            check(
                f"{self.name}: Tremor.high",
                self.tremor.high,
                Interval(float, None, self.rate / 2, closed="neither", unit="Hz"),
            )

    @property
    def kind(self) -> Kind:
        """The generating process: ``strokes``, ``oscillator`` or ``wander``."""
        return self.motion.kind

    def trials(self, n: int, duration: float = 60.0, seed: int = 0) -> list[Trial]:
        """Generate ``n`` independent solo trials.

        Trial k draws from its own stream, seeded by ``seed``, the person's name and k, so the
        same seed gives the same trials and trial k does not depend on ``n``; within a trial the
        motion, the tremor and the drop-outs draw from separate streams, so a person changed
        only in its tremor or drop-outs keeps the same motion.

        Parameters
        ----------
        n
            Number of trials.
        duration
            Length of each trial (s): samples at ``k / rate`` for every k with ``k / rate`` at
            most ``duration``.
        seed
            Non-negative integer.

        Returns
        -------
        list of Trial
            Labelled ``NAME-1`` .. ``NAME-n``, group the person's name, positions (units) clipped
            to the playing range, ``metadata`` holding the dataset (``synthetic``), the kind, the
            seed and the trial's number (``trial``, 1 to n).
        """
        check("n", n, Interval(int, 1, None))
        check("duration", duration, Interval(float, 1.0, 3600.0, unit="s"))
        check("seed", seed, Interval(int, 0, None))
        times = np.arange(math.floor(duration * self.rate + 1e-9) + 1) / self.rate
        name_key = zlib.crc32(self.name.encode("utf-8"))
        trials = []
        for k in range(1, n + 1):
            streams = np.random.SeedSequence([seed, name_key], spawn_key=(k,)).spawn(3)
            motion_rng, tremor_rng, dropout_rng = (np.random.default_rng(s) for s in streams)
            positions = self.motion.positions(times, motion_rng)
            if self.tremor is not None:
                positions += self.tremor.displacement(times.size, self.rate, tremor_rng)
            positions = np.clip(positions, *PLAYING_RANGE)
            if self.dropouts is not None:
                held = self.dropouts.held(times, dropout_rng)
                positions = positions[
                    np.maximum.accumulate(np.where(held, 0, np.arange(held.size)))
                ]
            metadata = {"dataset": "synthetic", "kind": self.kind, "seed": seed, "trial": k}
            trials.append(
                make_trial(
                    times, positions, label=f"{self.name}-{k}", group=self.name, metadata=metadata
                )
            )
        return trials


SYNTHETIC_PEOPLE: dict[str, SyntheticPerson] = {
    person.name: person
    for person in (
        SyntheticPerson(
            "ada",
            "Deliberate medium strokes with a short pause at each reversal; a clean 100 Hz record.",
            Strokes(0.35, 0.3, 0.7, 0.25, correlation=0.5, dwell=0.15),
        ),
        SyntheticPerson(
            "bruno",
            "Swings about 1 Hz over most of the range, pace and width drifting; Leap Motion "
            "record with occasional tracking losses.",
            Oscillation(1.0, 0.3, frequency_sd=0.1, amplitude_sd=0.05, time_constant=5.0),
            rate=LEAP_RATE,
            dropouts=DropOuts(0.03, 1.5),
        ),
        SyntheticPerson(
            "chloe",
            "Slow smooth wandering (corner 0.2 Hz); 60 Hz record.",
            Wander(0.2, 0.12, order=3),
            rate=60.0,
        ),
        SyntheticPerson(
            "dmitri",
            "Small quick strokes, no pause at reversals, a faint 8-10 Hz tremor; 60 Hz record.",
            Strokes(0.15, 0.4, 0.45, 0.3, correlation=0.3),
            rate=60.0,
            tremor=Tremor(0.002, 8.0, 10.0),
        ),
        SyntheticPerson(
            "elena",
            "Slow wide strokes with long pauses at the ends; Leap Motion record with tracking "
            "losses.",
            Strokes(0.5, 0.25, 1.6, 0.3, correlation=0.6, dwell=0.6),
            rate=LEAP_RATE,
            dropouts=DropOuts(0.05, 1.0),
        ),
        SyntheticPerson(
            "farid",
            "Fast narrow swings (1.4 Hz), steady pace, a 9-11 Hz tremor; 100 Hz record.",
            Oscillation(1.4, 0.2, frequency_sd=0.05, amplitude_sd=0.03, time_constant=10.0),
            tremor=Tremor(0.0015, 9.0, 11.0),
        ),
        SyntheticPerson(
            "greta",
            "Very slow drifting (corner 0.08 Hz); Leap Motion record with long tracking losses.",
            Wander(0.08, 0.13, order=3),
            rate=LEAP_RATE,
            dropouts=DropOuts(0.02, 2.5),
        ),
        SyntheticPerson(
            "hiro",
            "Wide unhurried swings (0.5 Hz) whose pace wanders quickly; 60 Hz record.",
            Oscillation(0.5, 0.33, frequency_sd=0.1, amplitude_sd=0.04, time_constant=3.0),
            rate=60.0,
        ),
        SyntheticPerson(
            "ines",
            "Hesitant strokes of very uneven length and pace, pauses, an 8-11 Hz tremor; 100 Hz "
            "record.",
            Strokes(0.25, 0.6, 1.0, 0.45, correlation=0.8, dwell=0.3),
            tremor=Tremor(0.003, 8.0, 11.0),
        ),
        SyntheticPerson(
            "jonas",
            "Livelier smooth wandering (corner 0.3 Hz) with frequent brief tracking losses; "
            "100 Hz record.",
            Wander(0.3, 0.1, order=4),
            dropouts=DropOuts(0.1, 0.3),
        ),
        SyntheticPerson(
            "kofi",
            "Quick wide strokes of even pace, a brief pause at each end; Leap Motion record.",
            Strokes(0.45, 0.35, 0.5, 0.2, correlation=0.7, dwell=0.1),
            rate=LEAP_RATE,
        ),
        SyntheticPerson(
            "lena",
            "Swings about 0.8 Hz of drifting width, a 9-12 Hz tremor; 60 Hz record with brief "
            "tracking losses.",
            Oscillation(0.8, 0.25, frequency_sd=0.06, amplitude_sd=0.06, time_constant=8.0),
            rate=60.0,
            tremor=Tremor(0.003, 9.0, 12.0),
            dropouts=DropOuts(0.05, 0.5),
        ),
        SyntheticPerson(
            "mateo",
            "Medium wandering (corner 0.15 Hz) with a faint 8-10 Hz tremor; 100 Hz record.",
            Wander(0.15, 0.11, order=2),
            tremor=Tremor(0.0015, 8.0, 10.0),
        ),
        SyntheticPerson(
            "nora",
            "Short strokes of uneven size, no pause; 100 Hz record with tracking losses.",
            Strokes(0.2, 0.5, 0.35, 0.35, correlation=0.4),
            dropouts=DropOuts(0.04, 0.8),
        ),
    )
}
"""The synthetic people by name; see the module's protocol for which ones a method may look at."""

DEVELOPMENT_PEOPLE = ("ada", "bruno", "chloe", "dmitri")
"""The people a method may be developed on (every design choice looks at these only)."""

TEST_PEOPLE = ("elena", "farid", "greta", "hiro", "ines", "jonas")
"""The held-out people: not looked at while choosing a method, only to report its result.

Reported once for the stroke generator's settings of issue 47 (whose last choice they had seen
an earlier result of); the next round of choices reports on `FRESH_PEOPLE` instead."""

FRESH_PEOPLE = ("kofi", "lena", "mateo", "nora")
"""People held out of every choice so far and never generated: the next round's test set."""
