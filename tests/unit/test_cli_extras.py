"""A command missing an optional extra's package names the extra that installs it."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from mirror_avatar.cli import OPTIONAL_MODULES, missing_extra

PYPROJECT = Path(__file__).parents[2] / "pyproject.toml"
NOT_FOR_COMMANDS = {"all", "docs", "dev"}


def declared_modules() -> dict[str, str]:
    """Each optional extra's own packages, as the top-level module each installs."""
    extras = tomllib.loads(PYPROJECT.read_text(encoding="utf-8"))["project"]
    modules = {}
    for extra, requirements in extras["optional-dependencies"].items():
        if extra in NOT_FOR_COMMANDS:
            continue
        for requirement in requirements:
            name, wanted = re.match(r"([A-Za-z0-9_.-]+)(?:\[([^]]*)\])?", requirement).groups()
            if name == "mirror-avatar":
                continue
            # dask[distributed] installs the package distributed too
            for package in [name, *(wanted.split(",") if wanted else [])]:
                modules[package.lower().replace("-", "_")] = extra
    return modules


def test_every_extras_package_is_named_with_its_extra():
    assert declared_modules() == OPTIONAL_MODULES


def test_a_missing_extras_module_is_one_line_naming_the_extra():
    error = ModuleNotFoundError("No module named 'websockets.asyncio'", name="websockets.asyncio")
    assert (
        missing_extra(error) == "this command needs websockets: pip install 'mirror-avatar[live]'"
    )


def test_a_missing_core_module_is_not_blamed_on_an_extra():
    assert missing_extra(ModuleNotFoundError("No module named 'scipy'", name="scipy")) is None
    assert missing_extra(ImportError("cannot import name 'x'", name="httpx")) is None
