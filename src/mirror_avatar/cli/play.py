"""``mirror-avatar play``: the live mirror game in a browser."""

from __future__ import annotations

import errno
import socket
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click

from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.common.errors import InputError

F = TypeVar("F", bound=Callable[..., Any])


def server_options(port: int, out: str, out_help: str) -> Callable[[F], F]:
    """Add the options of a command that serves pages: ``--host``, ``--port``, ``--out``.

    Parameters
    ----------
    port, out
        The default port and output folder.
    out_help
        What the output folder holds.
    """

    def decorate(command: F) -> F:
        options = (
            click.option(
                "--host", default="127.0.0.1", show_default=True, help="Address to listen on."
            ),
            click.option("--port", default=port, show_default=True, type=click.IntRange(0, 65535)),
            click.option(
                "--out",
                "out_dir",
                default=Path(out),
                show_default=True,
                type=click.Path(path_type=Path),
                help=out_help,
            ),
        )
        for option in reversed(options):
            command = option(command)
        return command

    return decorate


def listen(host: str, port: int) -> socket.socket:
    """Bind the listening socket of a command that serves pages (`server_options`).

    Raises
    ------
    InputError
        ``--port: port PORT on HOST is in use ...`` when another program listens there.
    """
    from mirror_avatar.realtime.transport import listening_socket

    try:
        return listening_socket(host, port)
    except OSError as error:
        if error.errno != errno.EADDRINUSE:
            raise
        raise InputError(
            "--port",
            f"port {port} on {host} is in use by another program: stop it, or choose another "
            "port with --port (0: any free port)",
        ) from None


@click.command()
@click.option(
    "--avatar",
    "avatar_spec",
    default=None,
    metavar="SPEC",
    help="The avatar (a player spec); default: a virtual trainer learned from the bundled data.",
)
@server_options(8765, "recordings", "Where trials are recorded (one folder per participant).")
@click.option(
    "--require-token",
    is_flag=True,
    help="Require the access token even on loopback (always required on other addresses).",
)
@click.option(
    "--max-sessions",
    default=8,
    show_default=True,
    type=click.IntRange(1, 64),
    help="Most players connected at once.",
)
@click.option(
    "--max-per-address",
    default=4,
    show_default=True,
    type=click.IntRange(1, 64),
    help="Most players connected from one computer (address).",
)
@click.option("--allow-host", "allowed_hosts", multiple=True, metavar="NAME",
              help="Without a token, also answer requests addressed to NAME (repeatable); "
              "loopback names always work.")  # fmt: skip
def play(
    avatar_spec: str | None,
    host: str,
    port: int,
    out_dir: Path,
    require_token: bool,
    max_sessions: int,
    max_per_address: int,
    allowed_hosts: tuple[str, ...],
) -> None:
    """Serve the mirror game on http://HOST:PORT and record every trial to OUT.

    Modes: solo, avatar leads, avatar follows and joint improvisation. Each trial is saved as it
    is played: the person's trial as CSV (time,position), a session CSV with both players in the
    avatar modes, and a JSON sidecar; an interrupted trial is kept and marked incomplete.
    """
    from mirror_avatar.live.server import LiveSettings, create_app
    from mirror_avatar.live.session import DEFAULT_AVATAR, make_avatar_factory
    from mirror_avatar.realtime.gates import is_loopback
    from mirror_avatar.realtime.transport import make_server, make_token

    spec = avatar_spec or DEFAULT_AVATAR
    token = make_token() if require_token or not is_loopback(host) else None
    check_output_dir(out_dir)
    factory = make_avatar_factory(spec)
    factory("avatar_follows")  # a bad spec fails here, before the server starts
    sock = listen(host, port)
    out_dir.mkdir(parents=True, exist_ok=True)
    settings = LiveSettings(
        out_dir=out_dir,
        avatar_spec=spec,
        token=token,
        allowed_hosts=frozenset(name.lower() for name in allowed_hosts),
        max_sessions=max_sessions,
        max_per_address=max_per_address,
    )
    port = sock.getsockname()[1]
    server = make_server(create_app(settings, factory), host, port, "info")
    shown = "localhost" if host in ("0.0.0.0", "::") else host
    url = f"http://{shown}:{port}/" + (f"?token={token}" if token else "")
    click.echo(f"mirror-avatar play: avatar {spec}; recording to {out_dir.resolve()}")
    if token:
        click.echo(f"access token: {token} (needed by every connection)")
    click.echo(f"open {url}  (Ctrl+C to stop)")
    server.run(sockets=[sock])
