"""The ``--scheduler`` option of the commands whose sessions a Dask cluster can play.

A Dask worker runs the code a peer sends it, and a plain ``tcp://`` scheduler lets any peer that
reaches it connect: such an address is taken only on this machine's loopback (where an SSH
tunnel's end also is), or with ``--insecure-scheduler``. Beyond it, a ``tls://`` scheduler
admits only peers whose certificate its CA signed (docs/cluster.md).
"""

from __future__ import annotations

import ipaddress
from collections.abc import Callable
from typing import Any, TypeVar
from urllib.parse import urlsplit

import click

from mirror_avatar.common.errors import InputError
from mirror_avatar.engine.batch import check_scheduler

F = TypeVar("F", bound=Callable[..., Any])

INSECURE = "insecure_scheduler"
"""Where ``--insecure-scheduler`` is kept in the command's context (``ctx.meta``)."""


def is_loopback(host: str | None) -> bool:
    """Return whether ``host`` (a name or an IP address) is this machine's loopback."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host or "").is_loopback
    except ValueError:
        return False


def check_encrypted(scheduler: str) -> None:
    """Refuse a plain-text scheduler address that leaves this machine.

    Raises
    ------
    InputError
        ``scheduler`` is neither ``tls://`` nor on loopback.
    """
    parts = urlsplit(scheduler if "://" in scheduler else f"tcp://{scheduler}")
    if parts.scheme != "tls" and not is_loopback(parts.hostname):
        raise InputError(
            scheduler,
            "a plain-text scheduler beyond this machine lets anyone who reaches it run code on "
            "the workers: use tls:// with certificates or an SSH tunnel (docs/cluster.md), or "
            "--insecure-scheduler on a network you trust",
        )


def _keep_insecure(ctx: click.Context, _param: click.Parameter, value: bool) -> bool:
    """Keep ``--insecure-scheduler`` for the ``--scheduler`` check (read first: it is eager)."""
    ctx.meta[INSECURE] = value
    return value


def _reachable_scheduler(
    ctx: click.Context, _param: click.Parameter, value: str | None
) -> str | None:
    """Check the scheduler when the command line is read, before any fitting or training."""
    if value is not None:
        if not ctx.meta.get(INSECURE):
            check_encrypted(value)
        check_scheduler(value)
    return value


def scheduler_option(what: str = "sessions") -> Callable[[F], F]:
    """Return the ``--scheduler`` and ``--insecure-scheduler`` options.

    ``--scheduler`` is a Dask scheduler whose workers play ``what``. It is checked
    (`check_encrypted`) and connected to (`mirror_avatar.engine.batch.check_scheduler`) as the
    option is read, so a plain-text address beyond loopback or an unreachable scheduler ends
    the command in one line before any work. ``--insecure-scheduler`` takes any plain-text one.
    """
    scheduler = click.option(
        "--scheduler",
        default=None,
        callback=_reachable_scheduler,
        help=f"Dask scheduler address (tls://host:port, or tcp:// on loopback): its workers "
        f"play the {what}; checked before any work starts.",
    )
    insecure = click.option(
        "--insecure-scheduler",
        is_flag=True,
        is_eager=True,
        expose_value=False,
        callback=_keep_insecure,
        help="Take a plain-text tcp:// scheduler beyond loopback (anyone who reaches it can run "
        "code on its workers).",
    )

    def decorate(command: F) -> F:
        return insecure(scheduler(command))

    return decorate
