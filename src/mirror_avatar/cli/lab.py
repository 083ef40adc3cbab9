"""``mirror-avatar lab``: lab sessions with a researcher's console (METHODS section 9)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from mirror_avatar.cli.lab_pilot import pilot
from mirror_avatar.cli.lab_preview import preview
from mirror_avatar.cli.lab_proxy import proxy
from mirror_avatar.cli.outputs import check_output_dir
from mirror_avatar.cli.play import listen, server_options
from mirror_avatar.common.errors import InputError

if TYPE_CHECKING:
    from mirror_avatar.realtime.tls import TlsFiles


@click.group(invoke_without_command=True)
@server_options(8766, "lab", "Where sessions are recorded (one folder per session).")
@click.option(
    "--lsl/--no-lsl",
    default=False,
    show_default=True,
    help="Publish each session as an LSL stream, which every machine on the network can "
    "discover, and accept LSL input devices (needs pylsl).",
)
@click.option(
    "--protocol",
    "protocol_file",
    type=click.Path(path_type=Path),
    default=None,
    help="A study protocol (TOML; see the lab guide, Study protocols): the console then "
    "creates each participant's run of it, in their counterbalanced order (the console can "
    "also load one).",
)
@click.option(
    "--certfile",
    type=click.Path(path_type=Path),
    default=None,
    help="The server's TLS certificate (PEM, with its chain): it serves HTTPS and secure "
    "WebSockets itself (needs --keyfile). Behind a reverse proxy that holds the certificate, "
    "leave it out.",
)
@click.option(
    "--keyfile",
    type=click.Path(path_type=Path),
    default=None,
    help="The private key of --certfile (PEM, unencrypted).",
)
@click.option(
    "--public-url",
    default=None,
    metavar="URL",
    help="The address participants reach the server at (https://study.example.org behind a "
    "reverse proxy): join links, QR codes and the printed console link use it.",
)
@click.pass_context
def lab(
    ctx: click.Context,
    host: str,
    port: int,
    out_dir: Path,
    lsl: bool,
    protocol_file: Path | None,
    certfile: Path | None,
    keyfile: Path | None,
    public_url: str | None,
) -> None:
    """Run lab sessions: people at their own screens and avatars, from a researcher's console.

    Serves on http://HOST:PORT (https:// with --certfile and --keyfile) and prints the console's
    URL with the researcher's token (the console always needs it). From the console, or its
    HTTP/JSON API, create a session (condition, people and avatars, graph, trials), hand each
    person their join link or QR code, then start, stop or abort; every sample is written to
    OUT/<session>/ as it is taken. `mirror-avatar lab export` turns a session into a
    BIDS-Motion dataset.
    """
    if ctx.invoked_subcommand is not None:
        return
    from mirror_avatar.lab.design.protocol import load_protocol
    from mirror_avatar.lab.running.public import parse_public_url
    from mirror_avatar.lab.running.server import LabSettings, create_lab_app
    from mirror_avatar.realtime.transport import make_server, make_token

    tls = _tls_files(certfile, keyfile)
    public = None if public_url is None else parse_public_url(public_url)
    protocol = None if protocol_file is None else load_protocol(protocol_file)
    check_output_dir(out_dir)
    if lsl and not _lsl_available():
        raise click.UsageError("--lsl needs pylsl: pip install 'mirror-avatar[lsl]'")
    if tls is not None:
        tls.check()
    sock = listen(host, port)
    out_dir.mkdir(parents=True, exist_ok=True)
    if lsl:
        _quiet_lsl()
    token = make_token()
    settings = LabSettings(
        out_dir=out_dir, token=token, lsl=lsl, protocol=protocol, public_url=public
    )
    port = sock.getsockname()[1]
    server = make_server(create_lab_app(settings), host, port, "info", tls=tls)
    shown = _reachable_name() if host in ("0.0.0.0", "::") else host
    scheme = "http" if tls is None else "https"
    console = public or f"{scheme}://{shown}:{port}"
    click.echo(f"mirror-avatar lab: recording to {out_dir.resolve()}; LSL {'on' if lsl else 'off'}")
    if protocol is not None:
        people = ", ".join(protocol.people)
        click.echo(
            f"protocol {protocol_file}: {protocol.title!r}, seed {protocol.seed}, people {people}"
        )
        for warning in protocol.warnings:
            click.echo(f"warning: {warning}", err=True)
        if protocol.seed_drawn:
            click.echo(
                f"warning: {protocol_file} has no seed: add 'seed = {protocol.seed}' to it, or a "
                "restart draws another and the participants' runs cannot resume",
                err=True,
            )
    click.echo(f"researcher's token: {token}")
    click.echo(f"console: {console}/console?token={token}  (Ctrl+C to stop)")
    if host in ("0.0.0.0", "::") and public is None:
        click.echo("join links use the address the console is opened at: open it at one the "
                   "participants' devices reach")  # fmt: skip
    server.run(sockets=[sock])


def _tls_files(certfile: Path | None, keyfile: Path | None) -> TlsFiles | None:
    """Return the server's certificate and key, or None without either (plain HTTP).

    Raises
    ------
    InputError
        One is given without the other.
    """
    from mirror_avatar.realtime.tls import TlsFiles

    if certfile is None and keyfile is None:
        return None
    if certfile is None or keyfile is None:
        given, missing = (
            ("--certfile", "--keyfile") if keyfile is None else ("--keyfile", "--certfile")
        )
        raise InputError(given, f"needs {missing} too (the certificate and its private key)")
    return TlsFiles(certfile, keyfile)


LSL_LOG_LEVEL = -1
"""liblsl's log level under ``mirror-avatar lab``: warnings and errors (its INFO lines about
configuration and versions would fill the console)."""


def _quiet_lsl() -> None:
    """Keep liblsl to warnings and errors (before any other LSL call)."""
    import pylsl

    pylsl.set_config_content(f"[log]\nlevel = {LSL_LOG_LEVEL}\n")


def _reachable_name() -> str:
    """Return this machine's address on the network (for a server on every address)."""
    import socket

    try:
        return socket.gethostbyname(socket.gethostname())
    except OSError:
        return "localhost"


def _lsl_available() -> bool:
    try:
        import pylsl  # noqa: F401
    except (ImportError, RuntimeError):
        return False
    return True


DATASET_FILES = ("dataset_description.json", "README", "participants.tsv", "participants.json")
"""The files `mirror_avatar.lab.export.bids.export_bids` writes at the top of a dataset (the
recordings' own names are known once the session is read)."""


@lab.command()
@click.argument("session_dir", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out_dir",
    required=True,
    type=click.Path(path_type=Path),
    help="The BIDS dataset folder (created, or merged into).",
)
def export(session_dir: Path, out_dir: Path) -> None:
    """Export the lab session in SESSION_DIR as BIDS-Motion (one file set per person and trial).

    A study session's folder (<protocol>-pNNN) exports the same way, its people as subjects
    sub-pNNN<label> (distinct for every participant): one run per trial, its block, condition
    and manipulations as events, the answers as beh files. Export each participant's folder
    into one --out to build the study's dataset.

    Every exported _motion.tsv is read back by `mirror-avatar evaluate` (the whole trial) and by
    `signature` or `generator fit` (that person's own motion).
    """
    from mirror_avatar.lab.export.bids import export_bids

    check_output_dir(out_dir, files=DATASET_FILES)
    written = export_bids(session_dir, out_dir)
    click.echo(f"wrote {len(written)} motion files to {out_dir.resolve()}")


lab.add_command(pilot)
lab.add_command(preview)
lab.add_command(proxy)
