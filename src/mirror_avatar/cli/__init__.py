"""The ``mirror-avatar`` command line.

Each command lives in its own module of this package and is registered on `cli` below. Bad input
(an `InputError`, or a usage error such as an unknown option) is printed as one line on standard
error and ends the program with exit code 2, never with a traceback.
"""

from __future__ import annotations

import sys

import click

from mirror_avatar.cli.convert import convert
from mirror_avatar.cli.evaluate import evaluate
from mirror_avatar.cli.generator import generator
from mirror_avatar.cli.group import group
from mirror_avatar.cli.info import info
from mirror_avatar.cli.play import play
from mirror_avatar.cli.reproduce import reproduce
from mirror_avatar.cli.signature import signature
from mirror_avatar.cli.simulate import simulate
from mirror_avatar.cli.train import train
from mirror_avatar.errors import InputError


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="mirror-avatar")
def cli() -> None:
    """Build avatars that move like a specific person and play the mirror game."""


cli.add_command(convert)
cli.add_command(generator)
cli.add_command(group)
cli.add_command(info)
cli.add_command(play)
cli.add_command(reproduce)
cli.add_command(signature)
cli.add_command(simulate)
cli.add_command(evaluate)
cli.add_command(train)


def main(argv: list[str] | None = None) -> int:
    """Run the command line and return its exit code (0 success, 2 bad input)."""
    try:
        cli.main(args=argv, prog_name="mirror-avatar", standalone_mode=False)
    except InputError as error:
        click.echo(f"mirror-avatar: error: {error}", err=True)
        return 2
    except click.exceptions.Exit as done:
        return int(done.exit_code)
    except click.Abort:
        click.echo("mirror-avatar: aborted", err=True)
        return 130
    except click.ClickException as error:
        click.echo(f"mirror-avatar: error: {error.format_message()}", err=True)
        return 2
    return 0


def run() -> None:
    """Console-script entry point: `main` with the process's arguments, then exit."""
    sys.exit(main())
