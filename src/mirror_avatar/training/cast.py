"""The paper's virtual "persons" (VT_1..VT_6) and who plays what in its cyber-player experiments.

The paper (METHODS section 7) fits one IMS generator per person, VT_1..VT_6, teaches a cyber
player to imitate person 5 against VT_1..VT_4 and keeps VT_6 unseen for validation. The bundled
data (`mirror_avatar.datasets.load_zhai2017`) has 18 trials of two styles, not six people, so
`make_virtual_trainers` builds six "persons" from six disjoint groups of three trials
(**choice**): fast-1..3, fast-4..6, fast-7..9, slow-1..3, slow-4..6, slow-7..9 -> VT1..VT6. The
target VT5 is then slow-4..6, a slow player, with seen partners VT1..VT3 (fast) and VT4 (slow)
and the unseen partner VT6 (slow). With data of three or more people, `cast_virtual_trainers`
makes one virtual trainer per person.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from mirror_avatar import dynamics
from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import draw_seeds
from mirror_avatar.files.trials import DEFAULT_RATE, Trial
from mirror_avatar.motion.generator import IMSGenerator
from mirror_avatar.motion.models import MotionModel
from mirror_avatar.players.virtual_trainer import VirtualTrainer

TARGET = 4
"""Index of the target, VT5 (the paper imitates person 5)."""

SEEN_PARTNERS = (0, 1, 2, 3)
"""Indices of the training partners VT1..VT4."""

UNSEEN_PARTNER = 5
"""Index of VT6, the partner never met in training."""


@dataclass(frozen=True, eq=False)
class VirtualTrainerSpec:
    """One virtual "person": a label, the trials it was fitted on and its motion model.

    Attributes
    ----------
    label
        ``"VT1"`` .. ``"VT6"``.
    trial_labels
        Labels of the trials its generator was fitted on.
    generator
        The fitted motion model (100 Hz): an `IMSGenerator` for the paper's VT1..VT6, a
        `mirror_avatar.motion.strokes.StrokeGenerator` for a personal avatar's person.
    """

    label: str
    trial_labels: tuple[str, ...]
    generator: MotionModel

    def player(self, role: str | dynamics.HKBParams) -> VirtualTrainer:
        """Make a virtual trainer with this person's generator and a role preset (or parameters)."""
        params = dynamics.preset(role) if isinstance(role, str) else role
        return VirtualTrainer(params, self.generator, label=self.label)


def make_virtual_trainers(
    trials: Sequence[Trial], n: int = 6, seed: int = 0, n_symbols: int = 256
) -> list[VirtualTrainerSpec]:
    """Fit one IMS generator per virtual "person": VT1..VTn from disjoint groups of trials.

    Trials are taken group by group in order of first appearance (``"fast"`` then ``"slow"`` for
    the bundled data), in their given order within a group, and each group is cut into ``n /
    n_groups`` consecutive blocks of equal size (leftover trials at a group's end are unused).
    With the bundled 18 trials and ``n = 6``: VT1..VT3 = fast-1..3, 4..6, 7..9 and VT4..VT6 =
    slow-1..3, 4..6, 7..9.

    Parameters
    ----------
    trials
        Solo trials (any rate; resampled to 100 Hz).
    n
        Number of virtual trainers; a multiple of the number of groups.
    seed
        Seeds the generators' k-means (each gets its own seed spawned from it).
    n_symbols
        Codebook size of every generator.

    Returns
    -------
    list of VirtualTrainerSpec
        VT1..VTn in order.

    Raises
    ------
    InputError
        If ``n`` is not a positive multiple of the number of groups or a group has fewer than
        ``n / n_groups`` trials.
    """
    groups: dict[str, list[Trial]] = {}
    for trial in trials:
        groups.setdefault(str(trial.group), []).append(trial)
    if n < 1 or not groups or n % len(groups):
        raise InputError("trainers", f"n = {n} is not a positive multiple of {len(groups)} groups")
    per_group = n // len(groups)
    blocks: list[list[Trial]] = []
    for name, members in groups.items():
        size = len(members) // per_group
        if size < 1:
            raise InputError("trials", f"group {name!r} has {len(members)} trials for {per_group}")
        blocks += [members[i * size : (i + 1) * size] for i in range(per_group)]
    return fit_trainers([f"VT{i + 1}" for i in range(n)], blocks, seed, n_symbols)


def fit_trainers(
    labels: Sequence[str], blocks: Sequence[Sequence[Trial]], seed: int, n_symbols: int
) -> list[VirtualTrainerSpec]:
    """Fit one IMS generator per block of trials (k-means seeds drawn from ``seed``)."""
    seeds = draw_seeds(seed, len(blocks))
    return [
        VirtualTrainerSpec(
            label,
            tuple(t.label for t in block),
            IMSGenerator(n_symbols=n_symbols, rate=DEFAULT_RATE, random_state=int(s)).fit(
                [t.resampled(DEFAULT_RATE) for t in block]
            ),
        )
        for label, block, s in zip(labels, blocks, seeds, strict=True)
    ]


@dataclass(frozen=True, eq=False)
class Cast:
    """Who plays what in the paper's cyber-player experiments (METHODS section 7).

    Attributes
    ----------
    trainers
        The virtual "persons".
    target
        Index of the person the cyber player imitates.
    seen
        Indices of the training partners.
    unseen
        Index of the partner never met in training.
    whole_people
        True when each virtual trainer is one person of the data (a group of trials); False
        for the bundled set-up of six blocks of two styles (`make_virtual_trainers`).
    """

    trainers: list[VirtualTrainerSpec]
    target: int
    seen: tuple[int, ...]
    unseen: int
    whole_people: bool

    def describe(self) -> str:
        """One sentence saying how the virtual trainers were made and who plays what."""
        made = "; ".join(f"{t.label}: {', '.join(t.trial_labels)}" for t in self.trainers)
        how = (
            "one virtual trainer per person of the data"
            if self.whole_people
            else f"{len(self.trainers)} virtual trainers from disjoint blocks of trials of each "
            "style (the data hold styles, not enough people)"
        )
        seen = ", ".join(self.trainers[i].label for i in self.seen)
        return (
            f"{how} ({made}). The target is {self.trainers[self.target].label}; the training "
            f"partners are {seen}; {self.trainers[self.unseen].label} is never met in training."
        )


def cast_virtual_trainers(trials: Sequence[Trial], seed: int = 0, n_symbols: int = 256) -> Cast:
    """Make the virtual trainers of the cyber-player experiments from the data (**choice**).

    With three or more groups (people) each is one virtual trainer, made from all its trials, in
    order of appearance; the second-to-last is the target, the last the unseen partner and the
    others the training partners (six people give the paper's VT5 target and VT6 unseen). With
    one or two groups (styles, as the bundled data), `make_virtual_trainers` makes six from
    blocks of trials: VT5 the target, VT1..VT4 the training partners and VT6 unseen.
    """
    groups: dict[str, list[Trial]] = {}
    for trial in trials:
        groups.setdefault(str(trial.group), []).append(trial)
    if len(groups) >= 3:
        trainers = fit_trainers(list(groups), list(groups.values()), seed, n_symbols)
        n = len(trainers)
        return Cast(trainers, n - 2, tuple(range(n - 2)), n - 1, True)
    trainers = make_virtual_trainers(trials, seed=seed, n_symbols=n_symbols)
    return Cast(trainers, TARGET, SEEN_PARTNERS, UNSEEN_PARTNER, False)
