"""The compiled loop over a set of player kinds, written from the kinds' registry.

numba cannot call a list of functions from compiled code without losing the direct calls
LLVM optimises, so the loop is written once per set of kinds (`mirror_avatar.players.kinds`):
a Python module whose loop unpacks each kind's arrays once, branches on each player's kind
code and calls that kind's step, then the solves of the kinds solved together. The module is
written beside the engine's own compiled code (``__pycache__/kind_loops``; the user's cache
directory when the package cannot be written), rewritten only when its text changes, and
compiled by numba with ``cache=True`` like any other, so a process loads it from disk;
`make clean-cache` removes its compiled code with the rest. `kind_loop` returns the loop, once
per process and set of kinds. Its first call in a process holds a lock on the module's file, so
processes that start together (test workers, Dask workers) compile and cache it one at a time
(numba's cache is not safe against several writers of one index).
"""

from __future__ import annotations

import importlib.util
import os
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

try:
    import fcntl
except ImportError:  # not POSIX: the first calls are not serialised between processes
    fcntl = None  # type: ignore[assignment]

from mirror_avatar.files.atomic import write_atomic_text
from mirror_avatar.players.kinds import PlayerKind, player_kind

HEADER = '''"""The compiled batch loop for the player kinds {names}.

Written by mirror_avatar.engine.dispatch from the kinds' registry; not to be edited.
"""

import numpy as np
from numba import njit

from mirror_avatar.players.base import gather_neighbours
{imports}


@njit(cache=True, nogil=True)
def run_kinds(
    kinds, slots, references, neighbour_index, neighbour_count, starts, out, {states}
):
    n_players, n = kinds.size, out.shape[2]
    out[2:, :, n - 1] = np.nan  # every other sample is written below
    for i in range(n_players):
        out[0, i, 0] = starts[i, 0]
        out[1, i, 0] = starts[i, 1]
{unpack}
    xs, vs, previous = np.empty(n_players), np.empty(n_players), np.empty(n_players)
    for k in range(n - 1):
        for i in range(n_players):
            m = neighbour_count[i]
            gather_neighbours(out[0], out[1], k, neighbour_index[i, :m], xs, vs, previous)
            x, v, reference = out[0, i, k], out[1, i, k], references[i, k]
            out[3, i, k] = reference
'''

ARGUMENTS = "slots[i], k, x, v, xs[:m], vs[:m], previous[:m], reference"

_LOCK = threading.Lock()
_LOOPS: dict[tuple[str, ...], Callable[..., None]] = {}


def kind_loop(names: tuple[str, ...]) -> Callable[..., None]:
    """Return the compiled loop of the kinds ``names`` (kind codes are positions in it).

    The loop takes ``(kinds, slots, references, neighbour_index, neighbour_count, starts, out,
    *states)``: each player's kind code and slot, shape (N,), the references (N, n - 1), the
    neighbour lists (N, N) and counts (N,), the initial states (N, 2), the output (4, N, n)
    written in place (`mirror_avatar.engine.compiled.run_plans`), and each kind's packed state.
    """
    with _LOCK:
        if names not in _LOOPS:
            _LOOPS[names] = _load(names, loop_source([player_kind(name) for name in names]))
        return _LOOPS[names]


def loop_source(kinds: list[PlayerKind]) -> str:
    """Return the text of the module holding the compiled loop of ``kinds``, in that order."""
    imports, unpack, branches, solves = [], [], [], []
    for code, kind in enumerate(kinds):
        imports.append(f"from {kind.step.__module__} import {kind.step.__name__} as step_{code}")
        fields = ", ".join(f"{kind.name}_{field}" for field in kind.state._fields)  # type: ignore[attr-defined]
        unpack.append(f"    ({fields},) = state_{code}")
        arguments = f"{fields}, {ARGUMENTS}"
        test = "if" if code == 0 else "elif"
        branches.append(f"            {test} kinds[i] == {code}:")
        if kind.solve is None:
            branches.append(
                "                out[0, i, k + 1], out[1, i, k + 1], out[2, i, k] = "
                f"step_{code}({arguments})"
            )
        else:
            imports.append(
                f"from {kind.solve.__module__} import {kind.solve.__name__} as solve_{code}"
            )
            branches.append(f"                step_{code}({arguments})")
            solves.append(f"        solve_{code}({fields}, k, out)")
    header = HEADER.format(
        names=", ".join(kind.name for kind in kinds),
        imports="\n".join(imports),
        unpack="\n".join(unpack),
        states=", ".join(f"state_{code}" for code in range(len(kinds))),
    )
    return header + "\n".join(branches + solves) + "\n"


def _load(names: tuple[str, ...], source: str) -> Callable[..., None]:
    """Write the module (when its text changed), import it and return its loop."""
    path = _directory() / f"loop_{'__'.join(names)}.py"
    if not path.is_file() or path.read_text(encoding="utf-8") != source:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic_text(path, source)
    module_name = f"mirror_avatar_kind_{path.stem}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load the compiled loop {path}")
    module: Any = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    spec.loader.exec_module(module)
    compiled = module.run_kinds

    def loop(*arguments: Any) -> None:
        if compiled.signatures:
            compiled(*arguments)
            return
        with _exclusive(path.with_suffix(".lock")):
            compiled(*arguments)  # loads the compiled loop, or compiles and caches it

    return loop


@contextmanager
def _exclusive(path: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``path`` (created if missing) across processes and threads."""
    with open(path, "w") as handle:
        if fcntl is not None:
            fcntl.flock(handle, fcntl.LOCK_EX)
        yield


def _directory() -> Path:
    """Where the loops are written: beside this module's compiled code, else the user's cache."""
    here = Path(__file__).parent
    if os.access(here, os.W_OK):
        return here / "__pycache__" / "kind_loops"
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return cache / "mirror-avatar" / "kind_loops"
