"""A personal avatar: one file holding a person's motor signature and their trained cyber players.

METHODS section 10: a person's solo trials -> their motion model -> their virtual trainer -> cyber
players trained, as follower and as leader, on sessions their virtual trainer plays with partners.
The file (``.npz`` + JSON, `mirror_avatar.files.model_files`) holds the motion model (its metadata
names its kind, `mirror_avatar.motion.models`: stroke generator by default, IMS generator when
absent, as in files written before the stroke generator) and both players
(tabular or deep: each role's metadata names its ``agent``, tabular when absent);
which one plays is chosen by the role a session gives it (`Avatar.player`, `POLICY_FOR_ROLE`):
the trained follower or leader, in groups the one whose coupling the group role shares, or, in
joint improvisation, where no policy fits, the person's own virtual trainer (their generator
with that role's preset). The player's label says which plays.
"""

from __future__ import annotations

import copy
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import HKBParams, preset
from mirror_avatar.files.importing import excerpt
from mirror_avatar.files.model_files import (
    check_object,
    join_parts,
    load_model,
    part_arrays,
    save_model,
)
from mirror_avatar.learning.acceleration_player import AccelerationPlayer
from mirror_avatar.motion.models import MotionModel, model_arrays, motion_from_arrays
from mirror_avatar.motion.sharing import shareable
from mirror_avatar.motion.strokes import StrokeGenerator
from mirror_avatar.players import Player, VirtualTrainer
from mirror_avatar.training.agents import agent_kind

FORMAT_NAME = "mirror-avatar/avatar"
FORMAT_VERSION = 1
TRAINED_ROLES = ("follower", "leader")
"""The roles an avatar holds a trained cyber player for."""

POLICY_FOR_ROLE = {
    "follower": "follower",
    "leader": "leader",
    "group": "follower",
    "group_leader": "leader",
}
"""The trained policy that plays each session role (**choice** for groups: a group member's
preset couples to the others with theta_p 0.85, near the follower's 0.9; a group leader's with
0.2, near the leader's 0.1). Roles not here (joint improvisation) play the virtual trainer."""

MAX_NAME_CHARS = 100
"""Longest avatar name (it names files and reports)."""


@dataclass
class Avatar:
    """A person's avatar: their motion model and their cyber players as follower and leader.

    Attributes
    ----------
    name
        Whom the avatar stands for.
    generator
        The person's motion model (`mirror_avatar.motion.models.MotionModel`: a stroke
        generator, or an IMS generator).
    players
        ``"follower"`` and ``"leader"`` -> the trained `CyberPlayer` or `DeepCyberPlayer`.
    summary
        How it was made and validated (JSON-serialisable).
    """

    name: str
    generator: MotionModel
    players: dict[str, AccelerationPlayer]
    summary: dict[str, Any] = field(default_factory=dict)

    def player(self, role: str | HKBParams) -> Player:
        """Return the player for a session role: its policy, else the person's virtual trainer.

        The policy is the one `POLICY_FOR_ROLE` names, labelled ``avatar NAME (ROLE policy)``
        (a copy: each call gives a player of its own); otherwise the virtual trainer, labelled
        ``avatar NAME (virtual trainer)``.

        Parameters
        ----------
        role
            A role preset name (`mirror_avatar.dynamics.ROLES`) or virtual-trainer parameters.
        """
        if isinstance(role, str) and role in POLICY_FOR_ROLE:
            policy = POLICY_FOR_ROLE[role]
            player = copy.copy(self.players[policy])
            player.label = f"avatar {self.name} ({policy} policy)"
            return player
        params = preset(role) if isinstance(role, str) else role
        return VirtualTrainer(params, self.generator, label=f"avatar {self.name} (virtual trainer)")

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the avatar to one ``.npz`` file, atomically."""
        arrays, generator_metadata = model_arrays(self.generator)
        parts = {"generator": arrays}
        metadata: dict[str, Any] = {
            "name": self.name,
            "summary": self.summary,
            "generator": generator_metadata,
        }
        for role in TRAINED_ROLES:
            player = self.players[role]
            parts[role], metadata[role] = player.model_arrays(path)
            metadata[role]["agent"] = player.agent
        return save_model(path, FORMAT_NAME, FORMAT_VERSION, join_parts(parts), metadata)


def load_avatar(path: str | os.PathLike[str]) -> Avatar:
    """Read an avatar written by `Avatar.save`, checking every part as its own loader does.

    Raises
    ------
    InputError
        ``path: problem`` for a missing, corrupt or inconsistent file, or a part that its own
        loader (`mirror_avatar.motion.models.motion_from_arrays`, the agent kind's
        `mirror_avatar.training.agents.AgentKind.from_arrays`) refuses.
    """
    arrays, metadata = load_model(path, FORMAT_NAME, FORMAT_VERSION, ())
    name = metadata.get("name")
    if not isinstance(name, str) or not 0 < len(name) <= MAX_NAME_CHARS:
        raise InputError(path, f"avatar name {excerpt(name)} is not a name")
    part = {name: part_arrays(arrays, name) for name in ("generator", *TRAINED_ROLES)}
    generator = motion_from_arrays(
        part["generator"], check_object(path, "generator", metadata.get("generator")), path
    )
    players = {
        role: _player_from_arrays(part[role], check_object(path, role, metadata.get(role)), path)
        for role in TRAINED_ROLES
    }
    for role, player in players.items():
        if player.training_.get("role") != role:
            raise InputError(
                path, f"its {role} was trained as {excerpt(player.training_.get('role'))}"
            )
    summary = check_object(path, "summary", metadata.get("summary", {}))
    return Avatar(name, generator, players, summary)


def shareable_avatar(avatar: Avatar, group_size: int) -> Avatar:
    """Return the avatar with its motion model's strokes averaged (`motion.sharing.shareable`).

    The motion model, and each player's reference motion when it is the same model, are
    replaced by one shareable model; the summary's trial labels by their number. The players'
    policies are kept: they were trained on sessions, not on the person's trials.

    Raises
    ------
    InputError
        The motion model is not a stroke generator, or `shareable` refuses it.
    """
    if not isinstance(avatar.generator, StrokeGenerator):
        raise InputError(
            "avatar",
            "its motion model is an IMS generator, whose frames are the person's recordings: "
            "only an avatar on a stroke generator can be shared (avatar create makes one)",
        )
    shared = shareable(avatar.generator, group_size)
    players = {}
    for role, player in avatar.players.items():
        players[role] = copy.copy(player)
        if player.reference is avatar.generator:
            players[role].reference = shared
    summary = dict(avatar.summary)
    if isinstance(summary.get("trials"), list):
        summary["trials"] = len(summary["trials"])
    return Avatar(avatar.name, shared, players, summary)


def _player_from_arrays(
    arrays: dict[str, Any], metadata: dict[str, Any], path: str | os.PathLike[str]
) -> AccelerationPlayer:
    """Rebuild one role's player with the loader its ``agent`` names (tabular when absent)."""
    return agent_kind(metadata.get("agent", "tabular"), path).from_arrays(arrays, metadata, path)
