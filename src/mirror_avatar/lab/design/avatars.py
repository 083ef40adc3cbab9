"""A lab plan's avatars: each loaded in its role, and the players its perturbations hand over to.

`load_avatar` reads an avatar's spec (`mirror_avatar.specs.load_player`: checked and dry-run),
refusing a recording it replays or follows over `MAX_RECORDING_SPEC_BYTES` before it is read;
`successor_players` builds the player each perturbation of a trial hands an avatar over to. A
protocol's checks build them when it is loaded, a trial when it opens.
"""

from __future__ import annotations

from collections.abc import Sequence

from mirror_avatar.files.user_files import check_regular
from mirror_avatar.lab.design.perturbation import Perturbation, successor
from mirror_avatar.lab.design.plan import SessionPlan
from mirror_avatar.players.base import Player
from mirror_avatar.specs import load_player, recording_file

MAX_RECORDING_SPEC_BYTES = 64 * 2**20
"""Largest recording an avatar spec may replay or follow in a lab session (bytes; **choice**:
an hour at 1 kHz as CSV is about 40 MB), checked before the file is read, so a session's
creation never reads a huge file into the server's memory."""


def load_avatar(spec: str, role: str) -> Player:
    """Load an avatar's player in its role (`mirror_avatar.specs.load_player`: checked, dry-run).

    A recording the spec replays or follows is refused before it is read when it is over
    `MAX_RECORDING_SPEC_BYTES` or no regular file (a device, a FIFO, a socket; a folder is left
    to `mirror_avatar.specs.load_player`, which says what to give instead).
    """
    recording = recording_file(spec)
    if recording is not None and recording.exists() and not recording.is_dir():
        check_regular(recording, MAX_RECORDING_SPEC_BYTES)
    return load_player(spec, role)


def successor_players(
    plan: SessionPlan, perturbations: Sequence[tuple[int, Perturbation]]
) -> list[tuple[int, Perturbation, Player]]:
    """Build the player each perturbation hands an avatar over to, in order (not reset).

    Each is its spec's player in the latest role with every parameter set so far
    (`mirror_avatar.lab.design.perturbation.successor`).
    """
    now: dict[int, tuple[str, dict[str, float]]] = {}
    built = []
    for k, perturbation in perturbations:
        spec = plan.slots[k].spec
        assert spec is not None
        role, values = now.get(k, (plan.roles[k], {}))
        role = perturbation.role or role
        values = values | dict(perturbation.values)
        now[k] = (role, values)
        built.append((k, perturbation, successor(spec, role, values)))
    return built
