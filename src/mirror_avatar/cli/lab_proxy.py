"""``mirror-avatar lab proxy``: an emulated internet between participants' pages and a lab."""

from __future__ import annotations

from pathlib import Path
from urllib.parse import urlsplit

import click

from mirror_avatar.cli.outputs import check_output_file
from mirror_avatar.cli.play import listen
from mirror_avatar.common.errors import InputError
from mirror_avatar.common.seeds import entropy_of

DEFAULT_LOG = Path("proxy-truth.csv")
"""Where the truth is written when --log is not given."""


def loopback_target(url: str) -> tuple[str, int]:
    """Return the host and port of a server's URL on this machine.

    Raises
    ------
    InputError
        ``--to: ...`` for a URL that is not ``http://HOST:PORT`` with HOST on loopback.
    """
    from mirror_avatar.realtime.gates import is_loopback

    parts = urlsplit(url)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme not in ("http", "ws") or not parts.hostname or port is None:
        raise InputError("--to", f"{url!r}: give the lab's address, such as http://127.0.0.1:8766")
    if not is_loopback(parts.hostname):
        raise InputError(
            "--to", f"{url!r}: the proxy forwards to this machine only (give 127.0.0.1:PORT)"
        )
    return parts.hostname, port


@click.command()
@click.option(
    "--to",
    "to_url",
    required=True,
    metavar="URL",
    help="The lab server the pages reach through the proxy (http://127.0.0.1:PORT).",
)
@click.option(
    "--network",
    "network_spec",
    required=True,
    metavar="SPEC",
    help="One-way delay in ms, per direction or both, and stalls: 80+-25, "
    "up=120+-40,down=40+-15, 120+-40,stall=5:1 (a stall 5 s after the start, for 1 s).",
)
@click.option(
    "--port",
    type=click.IntRange(0, 65535),
    default=0,
    show_default=True,
    help="The loopback port the pages use (0: any free port).",
)
@click.option(
    "--log",
    "log_file",
    type=click.Path(path_type=Path),
    default=DEFAULT_LOG,
    show_default=True,
    help="The truth log (CSV, a row per chunk carried; a .json beside it).",
)
@click.option(
    "--seed",
    type=click.IntRange(0),
    default=None,
    help="The seed of the delays (default: drawn and printed).",
)
def proxy(to_url: str, network_spec: str, port: int, log_file: Path, seed: int | None) -> None:
    """Put an emulated internet between participants' pages and a lab server on this machine.

    Listens on 127.0.0.1:PORT and forwards every connection to --to, delaying each chunk of data
    by a one-way delay drawn for it (normal, truncated at 0; never before the chunk sent before
    it, as TCP keeps order) and holding everything during a stall. Open the join links (or the
    console, whose links then go through the proxy too) at the address printed: the lab records
    those pages as it would participants at home. Every chunk's times are written to --log.
    """
    from mirror_avatar.common.interruptions import run_interruptible
    from mirror_avatar.remote.network import parse_network
    from mirror_avatar.remote.proxy import LOOPBACK, EmulatedInternet
    from mirror_avatar.remote.truth import companion

    target = loopback_target(to_url)
    network = parse_network(network_spec)
    check_output_file(log_file, ".csv", "--log", beside=[companion(log_file)])
    seed = entropy_of(seed)
    internet = EmulatedInternet(network, target, log_file, seed, listen(LOOPBACK, port))
    shown = f"http://{target[0]}:{target[1]}"

    async def serve() -> None:
        await internet.start()
        click.echo(f"mirror-avatar lab proxy: network {network}, seed {seed}; truth in {log_file}")
        click.echo(f"pages: open links at {internet.url} in place of {shown}  (Ctrl+C to stop)")
        await internet.serve()

    run_interruptible(serve())
