"""The ``--scheduler`` option of the commands whose sessions a Dask cluster can play."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import click

from mirror_avatar.engine.batch import check_scheduler

F = TypeVar("F", bound=Callable[..., Any])


def _reachable_scheduler(
    _ctx: click.Context, _param: click.Parameter, value: str | None
) -> str | None:
    """Check the scheduler when the command line is read, before any fitting or training."""
    if value is not None:
        check_scheduler(value)
    return value


def scheduler_option(what: str = "sessions") -> Callable[[F], F]:
    """Return the ``--scheduler`` option: a Dask scheduler whose workers play ``what``.

    The scheduler is connected to (`mirror_avatar.engine.batch.check_scheduler`) as the option
    is read, so an unreachable one ends the command in one line before any work.
    """
    return click.option(
        "--scheduler",
        default=None,
        callback=_reachable_scheduler,
        help=f"Dask scheduler address (tcp://host:port): its workers play the {what}; "
        "checked before any work starts.",
    )
