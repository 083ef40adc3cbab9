"""``mirror-avatar info``: versions of the toolkit and of what it runs on."""

from __future__ import annotations

import platform
from importlib.metadata import PackageNotFoundError, version

import click

DEPENDENCIES = (
    "numpy", "scipy", "scikit-learn", "numba", "shapely", "pandas", "pyarrow", "matplotlib",
    "click", "dask", "distributed", "gymnasium", "starlette", "uvicorn", "websockets",
    "segno", "pylsl",
)  # fmt: skip


def versions() -> dict[str, str]:
    """Installed version of the toolkit, Python and each dependency ("not installed" if absent)."""
    found = {"mirror-avatar": _version("mirror-avatar"), "python": platform.python_version()}
    found.update({name: _version(name) for name in DEPENDENCIES})
    return found


def _version(name: str) -> str:
    try:
        return version(name)
    except PackageNotFoundError:
        return "not installed"


@click.command()
def info() -> None:
    """Print the versions of mirror-avatar, Python and the libraries it uses."""
    for name, found in versions().items():
        click.echo(f"{name:14s} {found}")
    click.echo(f"{'platform':14s} {platform.platform()}")
