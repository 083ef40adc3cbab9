"""What each imported trial looks like, and what may be wrong with it.

A recording read with the wrong options often still reads: a tracker whose zero is at one end of
its travel gives positions in [0, 1] instead of [-0.5, 0.5], and every analysis runs on them.
`check_trial` measures each trial (mean rate, duration, the span of its positions, the span's
centre, the samples interpolated over drop-outs) and names what looks wrong: positions outside
the playing range `mirror_avatar.files.trials.PLAYING_RANGE`, a span whose centre is off the middle
of the range by more than `OFF_CENTRE`, or irregular sampling (a step longer than `IRREGULAR_STEP`
times the median step). `check_table` lays the checks out one line per trial; a trial resampled on
reading (``--resample``) shows its recorded and new rates (``13.1->100``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mirror_avatar.files.trials import PLAYING_RANGE, Trial

OFF_CENTRE = 0.1
"""Distance (units, a tenth of the playing range) of a trial's centre from 0 that is reported
(**choice**: players move about the middle of the range)."""

IRREGULAR_STEP = 1.5
"""A sampling step longer than this many median steps is reported as irregular (**choice**)."""

FIXES = {
    "outside": (
        "have positions outside the playing range",
        "move them with --centre or --offset, or check --position-unit and --playing-range",
    ),
    "off centre": (
        "move about a point off the middle of the playing range",
        "--centre moves each trial's centre to 0, --offset moves all of them by one amount",
    ),
    "irregular": ("are sampled irregularly", "analyses interpolate over the long steps"),
}
"""Each problem's words under the table, and what to do about it."""


@dataclass(frozen=True)
class TrialCheck:
    """The measures of one imported trial and its problems.

    Attributes
    ----------
    name
        The trial's source file (or label).
    rate
        Mean sampling rate (Hz).
    duration
        First to last sample (s).
    low, high
        Smallest and largest position (units).
    centre
        Middle of the positions' span, ``(low + high) / 2`` (units).
    interpolated
        Samples interpolated over drop-outs.
    recorded_rate
        Mean rate of the recording (Hz) when it was resampled to ``rate``; None otherwise.
    problems
        Short phrases naming what looks wrong; empty if nothing does.
    """

    name: str
    rate: float
    duration: float
    low: float
    high: float
    centre: float
    interpolated: int
    problems: tuple[str, ...]
    recorded_rate: float | None = None

    @property
    def rate_text(self) -> str:
        """The rate as the table shows it: ``13.1->100`` for a trial resampled."""
        if self.recorded_rate is None:
            return f"{self.rate:.4g}"
        return f"{self.recorded_rate:.3g}->{self.rate:.4g}"


def check_trial(trial: Trial) -> TrialCheck:
    """Measure ``trial`` and name its problems (see the module docstring)."""
    low, high = float(trial.positions.min()), float(trial.positions.max())
    centre = (low + high) / 2
    problems = []
    if low < PLAYING_RANGE[0] or high > PLAYING_RANGE[1]:
        problems.append(f"outside [{PLAYING_RANGE[0]:g}, {PLAYING_RANGE[1]:g}]")
    if abs(centre) > OFF_CENTRE:
        problems.append(f"off centre by {centre:+.2f}")
    steps = np.diff(trial.times)
    if steps.max() > IRREGULAR_STEP * np.median(steps):
        problems.append(f"irregular sampling (a step of {steps.max():.3g} s)")
    info = trial.metadata.get("import", {})
    return TrialCheck(
        name=_name(trial),
        rate=trial.rate,
        duration=trial.duration,
        low=low,
        high=high,
        centre=centre,
        interpolated=int(info.get("interpolated_samples", 0)),
        problems=tuple(problems),
        recorded_rate=trial.metadata.get("resampled_from"),
    )


def _name(trial: Trial) -> str:
    """Name a trial in the table: its source file (and player, of a file of several)."""
    name = str(trial.metadata.get("source") or trial.label)
    player = trial.metadata.get("player")
    return f"{name} ({player})" if player else name


def check_table(checks: Sequence[TrialCheck]) -> list[str]:
    """Lay ``checks`` out as text lines: a header, one line per trial, then the fixes needed."""
    width = max([len("trial"), *(len(check.name) for check in checks)])
    lines = [
        f"{'trial':<{width}}  {'rate Hz':>10}  {'length s':>8}  {'positions':>15}  "
        f"{'centre':>6}  {'filled':>6}  problems"
    ]
    for check in checks:
        span = f"{check.low:.2f} to {check.high:.2f}"
        lines.append(
            f"{check.name:<{width}}  {check.rate_text:>10}  {check.duration:>8.4g}  {span:>15}  "
            f"{check.centre:>+6.2f}  {check.interpolated:>6d}  "
            f"{'; '.join(check.problems) or 'none'}"
        )
    flagged = [check for check in checks if check.problems]
    for key, (words, fix) in FIXES.items():
        count = sum(any(p.startswith(key) for p in check.problems) for check in flagged)
        if count:
            lines.append(f"warning: {count} of {len(checks)} trial(s) {words}: {fix}")
    return lines
