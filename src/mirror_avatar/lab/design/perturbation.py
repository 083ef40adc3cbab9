"""Perturbations: an avatar's role or parameters changed mid-trial, at one sample, as an event.

A condition of a protocol lists them::

    perturb = [
      { at = 10.0, player = "A1", set = "leader" },            # a role
      { at = 20.0, player = "A1", set = "theta_p=0.5,omega=0.3" },  # named parameters
    ]

``at`` is seconds from each trial's start (sample ``round(at / T)``), ``player`` the label of an
``avatar`` or ``person-or-avatar`` slot (a person filling the slot is not perturbed), ``set`` a
role (`mirror_avatar.dynamics.ROLES`) or ``key=value`` pairs. What each avatar can change
(`changeable`) follows from its spec:

- a virtual trainer (``bundled:``, ``vt:``, a generator or curriculum-stage ``.npz``): a role
  (its preset end effector and cost) and the `mirror_avatar.dynamics.HKBParams` fields but
  ``period`` (``theta_p``, ``theta_v``, ``omega``, ``alpha``, ``beta``, ``gamma``, ``eta``);
- a personal avatar ``.npz``: a role its policies play (follower and leader, or group and
  group leader: `mirror_avatar.training.avatar.POLICY_FOR_ROLE`): the other trained policy
  takes over;
- a partner from the literature: its named parameters (`mirror_avatar.players.dynamical.
  ModelPartner.PARAMETERS` but those fixed in a trial), and for ``adaptive`` a role (the
  leader's or the follower's gains);
- a cyber-player ``.npz`` (one policy) or a replayed recording: nothing.

Changes accumulate within a trial: after each perturbation the avatar is its spec's player in
the latest role given (the condition's role before any) with every parameter set so far. That
player (the successor) is built and reset with the avatar's seed when the trial is opened, off
the clock; at the perturbation's sample k, before the players step from k to k + 1, it takes
over the avatar's trial (`mirror_avatar.players.base.Player.take_over`), so positions from sample
k + 1 on follow the change. Each trial's sidecar lists the perturbations applied under
``"perturbations"``: ``{"sample", "time_s", "player", "change"}`` (``change`` as
``role=leader`` or ``theta_p=0.5,omega=0.3``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import CONTROL_PERIOD, ROLES, preset
from mirror_avatar.dynamics.parameters import HKB_FIELDS, PARAMETER_RANGES
from mirror_avatar.files.model_files import read_archive
from mirror_avatar.lab.design.checker import Checker
from mirror_avatar.motion.generator import FORMAT_NAME as GENERATOR_FORMAT
from mirror_avatar.players.adaptive import AdaptivePlayer
from mirror_avatar.players.base import Player
from mirror_avatar.players.dynamical import parse_number, parse_options
from mirror_avatar.specs import MODEL_PARTNERS, load_player
from mirror_avatar.training.avatar import FORMAT_NAME as AVATAR_FORMAT
from mirror_avatar.training.avatar import POLICY_FOR_ROLE
from mirror_avatar.training.curriculum import FORMAT_NAME as STAGE_FORMAT

MAX_PERTURBATIONS = 20
"""Most perturbations in one condition."""

PERTURB_KEYS = ("at", "player", "set")
"""Keys of one perturbation."""

TRAINER_PARAMETERS = tuple(name for name in HKB_FIELDS if name != "period")
"""The virtual trainer's parameters a perturbation may set."""


@dataclass(frozen=True)
class Perturbation:
    """One change of an avatar at one sample of every trial of a condition.

    Attributes
    ----------
    at
        When (s from the trial's start).
    player
        The avatar's label.
    role
        The role it takes, or None.
    values
        The parameters it takes, by name.
    """

    at: float
    player: str
    role: str | None = None
    values: tuple[tuple[str, float], ...] = ()

    @property
    def sample(self) -> int:
        """The sample k before whose step the change is made (positions from k + 1 follow it)."""
        return round(self.at / CONTROL_PERIOD)

    @property
    def change(self) -> str:
        """The change as the sidecar records it: ``role=leader`` or ``theta_p=0.5,omega=0.3``."""
        if self.role is not None:
            return f"role={self.role}"
        return ",".join(f"{key}={value:g}" for key, value in self.values)


@dataclass(frozen=True)
class Changeable:
    """What a spec's player can change mid-trial: the roles it may take, its parameters' ranges."""

    roles: tuple[str, ...] = ()
    parameters: Mapping[str, tuple[float, float]] = field(default_factory=dict)


def changeable(spec: str) -> Changeable:
    """Return what the player of ``spec`` can change mid-trial (see the module docstring).

    A ``.npz`` spec's format is read from its metadata.

    Raises
    ------
    InputError
        A ``.npz`` spec that cannot be read.
    """
    name = spec.partition(":")[0]
    if name in MODEL_PARTNERS:
        kind = MODEL_PARTNERS[name]
        parameters = {
            key: (p.low, p.high)
            for key, p in kind.PARAMETERS.items()
            if key not in kind.FIXED_IN_TRIAL
        }
        return Changeable(ROLES if kind is AdaptivePlayer else (), parameters)
    trainer = Changeable(ROLES, {key: PARAMETER_RANGES[key] for key in TRAINER_PARAMETERS})
    if spec.startswith(("bundled:", "vt:")):
        return trainer
    if Path(spec).suffix.lower() != ".npz":
        return Changeable()
    _, metadata = read_archive(spec)
    kind_name = metadata.get("format")
    if kind_name in (GENERATOR_FORMAT, STAGE_FORMAT):
        return trainer
    if kind_name == AVATAR_FORMAT:
        return Changeable(tuple(POLICY_FOR_ROLE))
    return Changeable()


def successor(spec: str, role: str, values: Mapping[str, float]) -> Player:
    """Return the player of ``spec`` in ``role`` with the parameters ``values`` (not reset).

    A partner from the literature takes ``values`` over its spec's own; a virtual trainer takes
    them over its role's preset; a personal avatar takes none (its role's policy plays).

    Raises
    ------
    InputError
        A value out of its range, or parameters a virtual trainer refuses together.
    """
    name = spec.partition(":")[0]
    if name in MODEL_PARTNERS:
        kind = MODEL_PARTNERS[name]
        options = parse_options(spec, kind.PARAMETERS) | dict(values)
        return AdaptivePlayer(options, role) if kind is AdaptivePlayer else kind(options)
    if values:
        return load_player(spec, preset(role).with_(**values))
    return load_player(spec, role)


def parse_perturbations(
    check: Checker,
    value: object,
    where: str,
    specs: Mapping[str, str | None],
    roles: Mapping[str, str],
    duration: float,
) -> tuple[Perturbation, ...]:
    """Read and check a condition's ``perturb`` list.

    Parameters
    ----------
    check
        Builds the protocol's one-line errors.
    value
        The list as read from TOML.
    where
        Its key path (``blocks[1].conditions[0].perturb``).
    specs
        Each player label's avatar spec (None: a person).
    roles
        Each player label's role in the condition.
    duration
        A trial's length (s).
    """
    if value is None:
        return ()
    items = check.array(
        value, where, MAX_PERTURBATIONS, 'e.g. [{ at = 10.0, player = "A1", set = "leader" }]'
    )
    parsed = [
        _perturbation(check, item, f"{where}[{i}]", specs, duration) for i, item in enumerate(items)
    ]
    order = sorted(range(len(parsed)), key=lambda i: parsed[i].at)
    state: dict[str, tuple[str, dict[str, float]]] = {}
    seen: set[tuple[str, int]] = set()
    for i in order:
        perturbation, place = parsed[i], f"{where}[{i}]"
        key = (perturbation.player, perturbation.sample)
        if key in seen:
            raise check.error(
                f"{place}.at",
                f"{perturbation.player} is already perturbed at that sample",
                "merge the two",
            )
        seen.add(key)
        spec = specs[perturbation.player]
        assert spec is not None
        role, values = state.get(perturbation.player, (roles[perturbation.player], {}))
        role = perturbation.role or role
        values = values | dict(perturbation.values)
        _check_change(check, place, spec, perturbation, roles[perturbation.player], role, values)
        state[perturbation.player] = (role, values)
    return tuple(parsed[i] for i in order)


def _perturbation(
    check: Checker, value: object, where: str, specs: Mapping[str, str | None], duration: float
) -> Perturbation:
    data = check.table(value, where)
    check.keys(data, where, PERTURB_KEYS)
    label = data.get("player")
    if not isinstance(label, str) or label not in specs:
        known = ", ".join(specs)
        raise check.error(
            f"{where}.player", f"{label!r} plays no part in this condition", f"one of {known}"
        )
    spec = specs[label]
    if spec is None:
        raise check.error(
            f"{where}.player",
            f"{label} is a person, not an avatar",
            "perturb an avatar or a person-or-avatar",
        )
    at = data.get("at")
    last = duration - CONTROL_PERIOD
    ok = isinstance(at, int | float) and not isinstance(at, bool) and math.isfinite(at)
    if not ok or not CONTROL_PERIOD <= at <= last:  # type: ignore[operator]
        raise check.error(
            f"{where}.at",
            f"must be seconds within the trial, from {CONTROL_PERIOD:g} to {last:g}",
            "e.g. at = 10.0",
        )
    change = data.get("set")
    if not isinstance(change, str) or not change.strip():
        raise check.error(
            f"{where}.set", "must name a role or parameters", 'e.g. "leader" or "theta_p=0.5"'
        )
    if "=" not in change:
        return Perturbation(float(at), str(label), role=change.strip())  # type: ignore[arg-type]
    values = _values(check, f"{where}.set", change)
    return Perturbation(float(at), str(label), values=values)  # type: ignore[arg-type]


def _values(check: Checker, where: str, text: str) -> tuple[tuple[str, float], ...]:
    values: dict[str, float] = {}
    for item in text.split(","):
        key, _, raw = (part.strip() for part in item.partition("="))
        number = parse_number(raw)
        if not key or number is None or key in values:
            raise check.error(
                where, f"{item.strip()!r} is not a new key=number", 'e.g. "theta_p=0.5,omega=0.3"'
            )
        values[key] = number
    return tuple(values.items())


def _check_change(
    check: Checker,
    where: str,
    spec: str,
    perturbation: Perturbation,
    start: str,
    role: str,
    values: dict[str, float],
) -> None:
    """Refuse a change the avatar of ``spec`` cannot make, or values it refuses.

    ``start`` is the avatar's role in the condition, ``role`` and ``values`` what it plays
    once the change is made.
    """
    try:
        allowed = changeable(spec)
    except InputError as error:
        raise check.error(
            where, f"its avatar cannot be read: {error}", "fix the player's spec"
        ) from None
    if perturbation.role is not None and perturbation.role not in allowed.roles:
        can = f"roles {', '.join(allowed.roles)}" if allowed.roles else "no role"
        raise check.error(
            f"{where}.set", f"{spec} cannot take the role {perturbation.role!r}", f"it takes {can}"
        )
    if perturbation.role is not None and start not in allowed.roles:
        raise check.error(
            f"{where}.set",
            f"{spec} plays {start} in this condition, where it cannot change role",
            f"perturb it where it plays {' or '.join(allowed.roles)}",
        )
    for key, number in perturbation.values:
        if key not in allowed.parameters:
            known = ", ".join(allowed.parameters) or "none"
            raise check.error(
                f"{where}.set", f"{spec} has no parameter {key!r} to change", f"it takes {known}"
            )
        low, high = allowed.parameters[key]
        if not low <= number <= high:
            raise check.error(
                f"{where}.set", f"{key} must lie between {low:g} and {high:g}", "change the value"
            )
    if values and spec.partition(":")[0] not in MODEL_PARTNERS:
        try:
            preset(role).with_(**values)
        except InputError as error:
            raise check.error(f"{where}.set", error.problem, f"in the role {role}") from None
