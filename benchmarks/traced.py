"""Peak memory of a piece of work, traced in a run of its own.

tracemalloc slows every allocation of every thread, the batch engine's worker threads included,
so benchmarks time their runs untraced and measure memory in separate runs with
`peak_traced_mb`.
"""

from __future__ import annotations

import tracemalloc
from collections.abc import Callable


def peak_traced_mb(work: Callable[[], object]) -> float:
    """Run ``work`` under tracemalloc and return the peak traced memory (MB)."""
    tracemalloc.start()
    try:
        work()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return peak / 2**20
