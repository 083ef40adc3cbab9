"""The warm-up leaves every compiled kernel of the package in numba's cache on disk."""

from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

from numba.core.registry import CPUDispatcher

import mirror_avatar
from mirror_avatar.warm_up import warm_up


def package_kernels() -> dict[str, CPUDispatcher]:
    """Every numba function defined in a module of the package, by qualified name."""
    kernels = {}
    for module_info in pkgutil.walk_packages(mirror_avatar.__path__, "mirror_avatar."):
        module = importlib.import_module(module_info.name)
        for name, value in vars(module).items():
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == module.__name__:
                kernels[f"{module.__name__}.{name}"] = value
    return kernels


def cache_index(kernel: CPUDispatcher) -> Path:
    """Where numba keeps the index of a kernel's compiled versions."""
    return Path(kernel._cache._cache_file._index_path)


def test_every_kernel_is_cached_on_disk_after_the_warm_up() -> None:
    """Kernels inlined into their callers (``inline="always"``) are compiled only inside them;
    every other kernel, wherever in the package it is defined, has its cache index."""
    warm_up()
    kernels = package_kernels()
    compiled_alone = {
        name: kernel
        for name, kernel in kernels.items()
        if kernel.targetoptions.get("inline") != "always"
    }
    assert len(compiled_alone) > 50
    uncached = [name for name, kernel in compiled_alone.items() if not cache_index(kernel).exists()]
    assert uncached == []
