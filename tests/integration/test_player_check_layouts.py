"""`check_player` steps the package's players on the arrays the engine gives them.

A compiled step is compiled once per layout of its array arguments. The check's scripted
neighbours must be C-contiguous, as the engine's are, or checking a player compiles its kernels
again for strided arrays (seconds each) and exercises code that play never runs.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

LOADED_BY_THE_CHECK = """
import sys

from numba.core.registry import CPUDispatcher

from mirror_avatar.deep.player import DeepCyberPlayer
from mirror_avatar.dynamics import FOLLOWER
from mirror_avatar.engine.loop import play
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.players import VirtualTrainer, check_player
from mirror_avatar.specs import MODEL_PARTNERS, bundled_generator, model_partner

ACTIONS = (-4.0, -1.0, 0.0, 1.0, 4.0)


def cyber(kind):
    player = kind(actions=ACTIONS)
    player.initialise_policy(3)
    return player


FACTORIES = {
    "virtual trainer": lambda: VirtualTrainer(FOLLOWER, bundled_generator("slow")),
    "tabular": lambda: cyber(CyberPlayer),
    "deep": lambda: cyber(DeepCyberPlayer),
    **{name: (lambda name=name: model_partner(name)) for name in MODEL_PARTNERS},
}


def loaded():
    found = set()
    for module_name, module in list(sys.modules.items()):
        if module_name.startswith("mirror_avatar"):
            for value in vars(module).values():
                if isinstance(value, CPUDispatcher):
                    kernel = f"{value.py_func.__module__}.{value.py_func.__qualname__}"
                    found |= {(kernel, str(s)) for s in value.signatures}
    return found


for factory in FACTORIES.values():
    for size in (2, 4):  # one neighbour, three
        play([factory() for _ in range(size)], duration=1.0, seed=0)
played = loaded()
for factory in FACTORIES.values():
    check_player(factory, n_steps=20)
for kernel, signature in sorted(loaded() - played):
    print(f"{kernel}{signature}")
"""
"""A fresh process that plays every kind of the package's players, in a dyad and a group of
four, then checks each; it prints every compiled signature the check used and play did not."""


@pytest.mark.long
def test_checking_a_player_uses_the_layouts_play_uses() -> None:
    done = subprocess.run(
        [sys.executable, "-c", LOADED_BY_THE_CHECK],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
