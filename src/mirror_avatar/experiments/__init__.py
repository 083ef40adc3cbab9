"""The paper's validations, each a function from data to a report `Section`.

`EXPERIMENTS` lists them in report order; ``mirror-avatar reproduce`` runs them all. Each entry is
called as ``run(trials, quick=..., seed=...)`` with the bundled (or given) solo trials.
"""

from __future__ import annotations

from collections.abc import Callable

from mirror_avatar.experiments import (
    curriculum,
    cyber_player,
    generator,
    generator_complexity,
    group,
    signature,
    virtual_trainer,
)
from mirror_avatar.report import Section

EXPERIMENTS: list[tuple[str, Callable[..., Section]]] = [
    ("signature", signature.run),
    ("generator", generator.run),
    ("generator_complexity", generator_complexity.run),
    ("virtual_trainer", virtual_trainer.run),
    ("cyber_player", cyber_player.run),
    ("group", group.run),
    ("curriculum", curriculum.run),
]
"""(name, run) pairs in report order; ``run(trials, quick=False, seed=0) -> Section``."""

SWEEPS = frozenset({"generator_complexity", "curriculum"})
"""The long sweeps: ``reproduce`` runs them at their quick size unless ``--full`` is given (at full
size they take most of a full run's time)."""

AGENT_EXPERIMENTS = frozenset({"cyber_player", "group"})
"""The experiments that train a cyber player; their ``run`` also takes ``agent`` ("tabular" or
"dqn") and ``scheduler`` (a Dask scheduler's address, or None for local threads)."""
