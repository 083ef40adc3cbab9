"""Player specs: one string naming a player, as the command line and the live server take them.

A SPEC is one of:

- ``bundled:fast`` / ``bundled:slow``: a virtual trainer whose IMS generator is fitted on all nine
  bundled trials of that style (`mirror_avatar.datasets.load_zhai2017`, resampled to 100 Hz, k-means
  seed `BUNDLED_SEED`). Fitted generators are cached in-process and on disk (`cache_dir`).
- a motion model ``.npz`` (format ``mirror-avatar/stroke-generator`` or
  ``mirror-avatar/ims-generator``, `mirror_avatar.motion.models.load_motion`): a virtual trainer
  moving like that person;
- a cyber-player policy ``.npz`` (format ``mirror-avatar/cyber-player``, or
  ``mirror-avatar/deep-cyber-player`` for a deep one): the trained player (its dynamics are its
  own, so the role is not used);
- a personal avatar ``.npz`` (format ``mirror-avatar/avatar``,
  `mirror_avatar.training.avatar`): its cyber player for the role (follower or leader; in a group
  the follower, or the leader as group leader: `mirror_avatar.training.avatar.POLICY_FOR_ROLE`),
  or for joint improvisation the person's virtual trainer;
- a curriculum stage ``.npz`` (format ``mirror-avatar/curriculum-stage``,
  `mirror_avatar.training.curriculum`): a virtual trainer moving with the stage's motion;
- a recorded trial file (CSV, Parquet, MAT or BIDS-Motion,
`mirror_avatar.files.trial_files.read_trial`):
  the recording replayed open-loop (`RecordedPlayer`, the role is not used);
- ``vt:FILE`` with FILE a recorded trial: a virtual trainer whose reference velocity is that
  recording's;
- a partner from the literature, ``NAME`` or ``NAME:key=value,...`` with NAME one of
  `MODEL_PARTNERS` (``adaptive``, ``rpc``, ``hkb``, ``excitator``, ``kuramoto``) and keys from its
  ``PARAMETERS`` (the published values by default; METHODS "Virtual partners from the
  literature"). These names come first: a recording named like one is given as ``./NAME``.

Virtual trainers take the end-effector and cost parameters of the role. The format of an ``.npz``
file is read from its JSON metadata without unpickling.

Every player a spec names is checked when it is made: its parameters against their declared
ranges and orders (a partner's ``PARAMETERS`` and ``ORDERED``), then a dry run of
`mirror_avatar.players.base.DRY_RUN_SECONDS` against a scripted partner
(`mirror_avatar.players.base.dry_run`): a spec whose player stops being finite, leaves the
playing range or outruns `mirror_avatar.players.base.DRY_RUN_MAX_SPEED` is refused in one line
naming it (and, for a partner, the parameters it gives).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
from functools import lru_cache
from pathlib import Path

from mirror_avatar import __version__
from mirror_avatar.common.errors import InputError
from mirror_avatar.datasets import BUNDLED_STYLES, load_zhai2017
from mirror_avatar.deep.player import FORMAT_NAME as DEEP_FORMAT
from mirror_avatar.deep.player import load_deep_cyber_player
from mirror_avatar.dynamics import HKBParams, preset
from mirror_avatar.files.importing import DEFAULT_IMPORT, ImportOptions, excerpt
from mirror_avatar.files.model_files import read_archive
from mirror_avatar.files.trial_files import read_trial
from mirror_avatar.files.trials import DEFAULT_RATE, Trial
from mirror_avatar.files.user_files import check_path
from mirror_avatar.learning.acceleration_player import AccelerationPlayer
from mirror_avatar.learning.agent import FORMAT_NAME as CYBER_FORMAT
from mirror_avatar.learning.agent import load_cyber_player
from mirror_avatar.motion.generator import FORMAT_NAME as GENERATOR_FORMAT
from mirror_avatar.motion.generator import PAPER_EMISSION, PAPER_SYMBOLS, IMSGenerator
from mirror_avatar.motion.models import load_motion
from mirror_avatar.motion.strokes import FORMAT_NAME as STROKES_FORMAT
from mirror_avatar.players import Player, RecordedPlayer, VirtualTrainer
from mirror_avatar.players.adaptive import AdaptivePlayer
from mirror_avatar.players.base import dry_run
from mirror_avatar.players.dynamical import ModelPartner, parse_options
from mirror_avatar.players.excitator import ExcitatorPartner
from mirror_avatar.players.hkb_partner import HKBPartner
from mirror_avatar.players.kuramoto import KuramotoPlayer
from mirror_avatar.players.rpc import ReactivePredictivePlayer
from mirror_avatar.training.avatar import FORMAT_NAME as AVATAR_FORMAT
from mirror_avatar.training.avatar import load_avatar
from mirror_avatar.training.curriculum import FORMAT_NAME as STAGE_FORMAT
from mirror_avatar.training.curriculum import load_stage

__all__ = [
    "BUNDLED_SEED",
    "BUNDLED_STYLES",
    "MODEL_PARTNERS",
    "bundled_generator",
    "cache_dir",
    "load_player",
    "model_partner",
]

BUNDLED_SEED = 0
"""k-means seed of the generators fitted on the bundled styles (**choice**)."""

MODEL_PARTNERS: dict[str, type[ModelPartner]] = {
    "adaptive": AdaptivePlayer,
    "rpc": ReactivePredictivePlayer,
    "hkb": HKBPartner,
    "excitator": ExcitatorPartner,
    "kuramoto": KuramotoPlayer,
}
"""The partners from the literature by spec name."""

SPEC_FORMS = (
    "bundled:fast, bundled:slow, vt:TRIAL_FILE, a model .npz, a trial file or "
    + ", ".join(f"{name}[:key=value,...]" for name in MODEL_PARTNERS)
)


POLICY_ROLES = {"follower": ("follower",), "leader": ("leader",), "group": ("group", "joint")}
"""The roles a cyber player trained in each role (``training_["role"]``) may play."""


def load_player(
    spec: str, role: str | HKBParams, options: ImportOptions = DEFAULT_IMPORT
) -> Player:
    """Build the player a spec names.

    Parameters
    ----------
    spec
        See the module docstring.
    role
        A role preset name (`mirror_avatar.dynamics.ROLES`) or the parameters of the virtual
        trainer. A recorded player ignores it; a cyber player refuses a role it was not trained
        for (`POLICY_ROLES`).
    options
        How a recorded trial file is read (columns, units, gaps).

    Returns
    -------
    Player
        Reset and dry-run (see the module docstring): reset it again before use.

    Raises
    ------
    InputError
        ``spec: problem`` for an unknown spec, an unknown role, a missing or unreadable file, a
        cyber player asked to play a role it was not trained for, or a player that diverges in
        its dry run.
    """
    if spec.partition(":")[0] in MODEL_PARTNERS:
        return model_partner(spec, role if isinstance(role, str) else "follower")
    player = _build_player(spec, role, options)
    dry_run(player, spec)
    return player


def _build_player(spec: str, role: str | HKBParams, options: ImportOptions) -> Player:
    """Build the player of a spec that names no partner from the literature (`load_player`)."""
    params = preset(role) if isinstance(role, str) else role
    label = f"virtual trainer ({spec})"
    if spec.startswith("bundled:"):
        style = spec.removeprefix("bundled:")
        if style not in BUNDLED_STYLES:
            raise InputError(
                spec, f"unknown bundled style {excerpt(style)}; expected one of {BUNDLED_STYLES}"
            )
        return VirtualTrainer(params, bundled_generator(style), label=label)
    if spec.startswith("vt:"):
        trial = _read_recording(spec.removeprefix("vt:"), options)
        return VirtualTrainer(params, trial, label=label)
    path = check_path(spec)
    if path.suffix.lower() == ".npz":
        return _load_model(path, role, label)
    if not path.exists():
        raise InputError(spec, f"no such file, and not a player spec ({SPEC_FORMS})")
    if path.is_dir():
        raise InputError(
            spec,
            f"is a folder, a player is one file: fit a model on its trials (mirror-avatar "
            f"generator fit {spec} --out MODEL.npz) and give MODEL.npz, or give one trial file",
        )
    return RecordedPlayer(_read_recording(spec, options))


def recording_file(spec: str) -> Path | None:
    """Return the trial file a spec replays or follows (``vt:FILE``, a trial file), else None."""
    if spec.partition(":")[0] in MODEL_PARTNERS or spec.startswith("bundled:"):
        return None
    path = Path(spec.removeprefix("vt:"))
    return None if path.suffix.lower() == ".npz" else path


def replays_recording(spec: str) -> bool:
    """Whether a spec replays a recorded trial open-loop (a trial file; ``vt:FILE`` follows one)."""
    return recording_file(spec) is not None and not spec.startswith("vt:")


def model_partner(spec: str, role: str = "follower") -> ModelPartner:
    """Build the partner from the literature that ``NAME[:key=value,...]`` names, dry-run.

    The adaptive player takes the leader's gains in a leading role; the others ignore the role.

    Raises
    ------
    InputError
        ``spec: problem``: a value that is no plain number, out of its range or out of order
        with another (``ORDERED``), or a partner that diverges in its dry run.
    """
    kind = MODEL_PARTNERS[spec.partition(":")[0]]
    options = parse_options(spec, kind.PARAMETERS)
    try:
        player = AdaptivePlayer(options, role) if kind is AdaptivePlayer else kind(options)
    except InputError as error:
        raise InputError(spec, error.problem) from None
    dry_run(player, spec, player.given())
    return player


def _read_recording(path: str, options: ImportOptions) -> Trial:
    return read_trial(path, options).resampled(DEFAULT_RATE)


def _load_model(path: Path, role: str | HKBParams, label: str) -> Player:
    _, metadata = read_archive(path)
    kind = metadata.get("format")
    if kind in (STROKES_FORMAT, GENERATOR_FORMAT):
        params = preset(role) if isinstance(role, str) else role
        return VirtualTrainer(params, load_motion(path), label=label)
    if kind in (CYBER_FORMAT, DEEP_FORMAT):
        player = load_cyber_player(path) if kind == CYBER_FORMAT else load_deep_cyber_player(path)
        if isinstance(role, str):
            _check_policy_role(path, player, role)
        return player
    if kind == AVATAR_FORMAT:
        return load_avatar(path).player(role)
    if kind == STAGE_FORMAT:
        params = preset(role) if isinstance(role, str) else role
        return VirtualTrainer(params, load_stage(path), label=label)
    formats = (
        STROKES_FORMAT,
        GENERATOR_FORMAT,
        CYBER_FORMAT,
        DEEP_FORMAT,
        AVATAR_FORMAT,
        STAGE_FORMAT,
    )
    known = ", ".join(repr(k) for k in formats)
    raise InputError(path, f"model format {excerpt(kind)} is none of {known}")


def _check_policy_role(path: Path, player: AccelerationPlayer, role: str) -> None:
    trained = player.training_.get("role")
    if trained in POLICY_ROLES and role not in POLICY_ROLES[trained]:
        raise InputError(
            path,
            f"a cyber player trained as {trained} cannot play {role}: train one for that role "
            "(train --role, or group train), or use this one as "
            + " or ".join(POLICY_ROLES[trained]),
        )


def cache_dir() -> Path:
    """Directory of cached fitted models: ``$XDG_CACHE_HOME/mirror-avatar`` (``~/.cache``)."""
    root = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(root) / "mirror-avatar"


@lru_cache(maxsize=len(BUNDLED_STYLES))
def bundled_generator(style: str) -> IMSGenerator:
    """Return the IMS generator fitted on all bundled trials of ``style`` at 100 Hz.

    The fitted model is kept on disk under `cache_dir`, in a file named by a hash of the style,
    the generator's parameters and the package version; it is written atomically, and a file
    that cannot be read back is refitted and overwritten. An unwritable cache only costs a refit.

    Parameters
    ----------
    style
        One of `BUNDLED_STYLES`.
    """
    model = IMSGenerator(
        n_symbols=PAPER_SYMBOLS,
        rate=DEFAULT_RATE,
        random_state=BUNDLED_SEED,
        emission=PAPER_EMISSION,
    )
    key = json.dumps(
        {"style": style, "parameters": model.get_params(), "version": __version__}, sort_keys=True
    )
    path = cache_dir() / f"bundled-{style}-{hashlib.sha256(key.encode()).hexdigest()[:16]}.npz"
    if path.is_file():
        try:
            return IMSGenerator.load(path)
        except InputError:
            pass
    trials = [t.resampled(DEFAULT_RATE) for t in load_zhai2017() if t.group == style]
    model.fit(trials)
    with contextlib.suppress(OSError):
        model.save(path)
    return model
