"""What a participant's page needs to step an avatar's player itself: its arrays, as one message.

`browser_arrays` turns a player into a JSON-serialisable message that the page's player module
(``lab/static/avatars.js``) builds the same player from and steps with the observations the
Python player gets, position for position (METHODS section 16). The numbers come from the
player's plan for the compiled batch loop (`mirror_avatar.players.base.PlayerPlan`), which holds
the arrays its model file holds (a Q-table and its bin edges, a network's flat parameters, a
recording on the control grid), and from the constants of the modules that define the step
(the playing range, the network's input scales): the page holds none of them.

The kinds the page runs are the deterministic steps: a recording (``recorded``), the tabular
cyber player's greedy step (``cyber``) and the deep cyber player's (``deep``). A learned player
whose policy reads its own reference velocity gets it drawn here, from its seed, as its
`reset` draws it (the generator's chain walk stays in Python). Any other player (a virtual
trainer, a model partner) is refused in one line.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import entropy_of
from mirror_avatar.deep import features
from mirror_avatar.deep.player import NetworkPolicy
from mirror_avatar.dynamics import HKBParams
from mirror_avatar.files.trials import PLAYING_RANGE
from mirror_avatar.learning.agent import GreedyPolicy
from mirror_avatar.players import Player
from mirror_avatar.players.base import PlayerPlan
from mirror_avatar.players.reference import draw_references

FORMAT_NAME = "mirror-avatar/browser-player"
FORMAT_VERSION = 1
BROWSER_KINDS = ("recorded", "cyber", "deep")
"""The kinds of player (`PlayerPlan.kind`) the page steps."""


def browser_arrays(player: Player, seed: int | None, n_steps: int) -> dict[str, Any]:
    """Return the message from which the page builds ``player`` and steps it.

    Parameters
    ----------
    player
        The player, as the server would run it.
    seed
        The seed its `Player.reset` would get (draws a reference velocity, when its policy reads
        one); None draws fresh entropy, recorded in the message as ``seed``.
    n_steps
        Control periods the page will step it for (references drawn for them).

    Returns
    -------
    dict
        ``format``, ``version``, ``kind`` (one of `BROWSER_KINDS`), ``label``, ``period`` (s),
        ``seed`` (the entropy drawn from, as text: it may exceed a double's 53 bits), ``start``
        (position, velocity), ``range`` (the playing range, units) and ``arrays``, each an
        object of ``shape`` and row-major ``data``. Learned players add ``dynamics`` (the HKB
        end effector and its RK4 substeps) and their policy's layout (``features``, or
        ``network`` with the input scales).

    Raises
    ------
    InputError
        ``LABEL: problem`` for a player the page cannot step, naming where it runs.
    """
    entropy = entropy_of(seed)
    plan = player.plan(entropy, n_steps)
    if plan is None or plan.kind not in BROWSER_KINDS:
        raise InputError(
            player.label,
            f"a {type(player).__name__} cannot be stepped in the browser (only "
            f"{', '.join(BROWSER_KINDS)} players can): run it on the server",
        )
    message: dict[str, Any] = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "kind": plan.kind,
        "label": player.label,
        "period": float(player.period),
        "seed": str(entropy),
        "start": [float(plan.start[0]), float(plan.start[1])],
        "range": [float(PLAYING_RANGE[0]), float(PLAYING_RANGE[1])],
    }
    if plan.kind == "recorded":
        assert plan.track is not None
        return message | {"arrays": {"track": _array(plan.track)}}
    return message | _learned(plan)


def _learned(plan: PlayerPlan) -> dict[str, Any]:
    """Return the end effector, policy and drawn reference of a learned player's plan."""
    assert plan.params is not None
    policy = plan.policy
    arrays = {"actions": _array(policy.actions)}
    if plan.reference is not None:
        arrays["reference"] = _array(draw_references([plan.reference])[0])
    layout: dict[str, Any]
    if isinstance(policy, GreedyPolicy):
        disc = policy.discretisation
        arrays |= {
            "q_table": _array(policy.q_table),
            "edges": _array(disc.flat_edges),
            "offsets": _array(disc.offsets),
        }
        layout = {"features": disc.features}
    else:
        assert isinstance(policy, NetworkPolicy)
        arrays |= {"weights": _array(policy.weights), "sizes": _array(policy.sizes)}
        layout = {"network": _network(policy)}
    return {"dynamics": _dynamics(plan.params, policy.n_substeps), "arrays": arrays} | layout


def _dynamics(params: HKBParams, n_substeps: int) -> dict[str, float | int]:
    """Return the end effector as `mirror_avatar.dynamics.integrate_hkb` reads it."""
    names = ("alpha", "beta", "gamma", "omega", "period")
    return {name: float(getattr(params, name)) for name in names} | {"n_substeps": n_substeps}


def _network(policy: NetworkPolicy) -> dict[str, Any]:
    """Return the input layout and scales of `mirror_avatar.deep.features.encode`."""
    return {
        "n_slots": int(policy.n_slots),
        "use_reference": bool(policy.use_reference),
        "position_scale": features.POSITION_SCALE,
        "velocity_scale": features.VELOCITY_SCALE,
        "relative_position_scale": features.RELATIVE_POSITION_SCALE,
        "relative_velocity_scale": features.RELATIVE_VELOCITY_SCALE,
        "slot_width": features.SLOT_WIDTH,
    }


def _array(values: NDArray[Any]) -> dict[str, Any]:
    """Return an array as the message holds it: its shape and its values in row-major order.

    JSON writes each float64 as the shortest text that reads back to the same double, so the
    page reads the very numbers the player holds.
    """
    return {"shape": list(values.shape), "data": np.ravel(values).tolist()}
