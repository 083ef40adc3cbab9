"""mirror-avatar: artificial players that move like a specific person in the mirror game."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("mirror-avatar")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0"

__all__ = ["__version__"]
