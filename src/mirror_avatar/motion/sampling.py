"""New trials from a fitted motion model, as both generators make them."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.files.trials import Trial, make_trial

Seed = int | np.random.Generator | None


def sample_trials(
    sample_positions: Callable[[int, np.random.Generator], NDArray[np.float64]],
    rate: float,
    groups: Sequence[str],
    generator: str,
    duration: float,
    n: int,
    random_state: Seed,
) -> list[Trial]:
    """Generate ``n`` trials of ``duration`` seconds at ``rate`` Hz from one random stream.

    ``sample_positions(n_samples, rng)`` makes one trial's positions (units). Trials are labelled
    ``generated-1..n``, their group the training ``groups`` joined by "+", and their metadata
    names the ``generator``, the seed (an int ``random_state``, else None) and the index.

    Raises
    ------
    InputError
        A duration or count that is not positive.
    """
    if not (duration > 0 and n >= 1):
        raise InputError("generator", "duration and n must be positive")
    rng = np.random.default_rng(random_state)
    n_samples = int(round(duration * rate)) + 1
    times = np.arange(n_samples) / rate
    seed = random_state if isinstance(random_state, int) else None
    return [
        make_trial(
            times,
            sample_positions(n_samples, rng),
            label=f"generated-{k + 1}",
            group="+".join(groups),
            metadata={"generator": generator, "seed": seed, "index": k},
        )
        for k in range(n)
    ]
