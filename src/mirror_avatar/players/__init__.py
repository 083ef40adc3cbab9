"""Players: the protocol every player follows and the built-in kinds.

`base` declares the protocol (`Player`, `ExternalPlayer`, `Observation`, `check_player`),
`reference` draws reference velocities, `virtual_trainer` and `recorded` are two kinds of player;
the cyber player is `mirror_avatar.learning.agent.CyberPlayer`.
"""

from mirror_avatar.players.base import (
    ExternalPlayer,
    Observation,
    Player,
    PlayerCheckError,
    check_player,
)
from mirror_avatar.players.recorded import RecordedPlayer
from mirror_avatar.players.reference import ReferenceTrack, draw_reference
from mirror_avatar.players.virtual_trainer import VirtualTrainer

__all__ = [
    "ExternalPlayer",
    "Observation",
    "Player",
    "PlayerCheckError",
    "RecordedPlayer",
    "ReferenceTrack",
    "VirtualTrainer",
    "check_player",
    "draw_reference",
]
