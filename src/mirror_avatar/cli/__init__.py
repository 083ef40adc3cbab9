"""The ``mirror-avatar`` command line.

Each command lives in its own module of this package and is registered on `cli` below. Bad input
(an `InputError`, a usage error such as an unknown option, or a file the system refuses) is
printed as one line on standard error and ends the program with exit code 2; anything else that
goes wrong is one line too, with exit code 1 (``MIRROR_AVATAR_DEBUG=1`` shows the traceback).
Interrupted (Ctrl+C, SIGTERM or SIGHUP, unless ignored when the program started: the console
script `mirror_avatar.console.run` handles them from its first instant, and waits for compiling
to finish), a command stops its batch workers and exits with code 130, naming the signal.
"""

from __future__ import annotations

import os

import click

from mirror_avatar.cli.avatar import avatar
from mirror_avatar.cli.benchmark import benchmark
from mirror_avatar.cli.convert import convert
from mirror_avatar.cli.curriculum import curriculum
from mirror_avatar.cli.evaluate import evaluate
from mirror_avatar.cli.generator import generator
from mirror_avatar.cli.group import group
from mirror_avatar.cli.info import info
from mirror_avatar.cli.lab import lab
from mirror_avatar.cli.play import play
from mirror_avatar.cli.reproduce import reproduce
from mirror_avatar.cli.signature import signature
from mirror_avatar.cli.simulate import simulate
from mirror_avatar.cli.study import study
from mirror_avatar.cli.train import train
from mirror_avatar.errors import InputError
from mirror_avatar.interruptions import aborted, interrupt

__all__ = ["cli", "fail", "interrupt", "main"]


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="mirror-avatar")
def cli() -> None:
    """Build avatars that move like a specific person and play the mirror game."""


cli.add_command(avatar)
cli.add_command(benchmark)
cli.add_command(convert)
cli.add_command(curriculum)
cli.add_command(generator)
cli.add_command(group)
cli.add_command(info)
cli.add_command(lab)
cli.add_command(play)
cli.add_command(reproduce)
cli.add_command(signature)
cli.add_command(simulate)
cli.add_command(study)
cli.add_command(evaluate)
cli.add_command(train)


def main(argv: list[str] | None = None) -> int:
    """Run the command line and return its exit code (0 success, 2 bad input, 1 failure)."""
    try:
        cli.main(args=argv, prog_name="mirror-avatar", standalone_mode=False)
    except InputError as error:
        return fail(str(error))
    except click.exceptions.Exit as done:
        return int(done.exit_code)
    except (click.Abort, KeyboardInterrupt) as stop:
        return aborted(stop)
    except click.ClickException as error:
        return fail(error.format_message())
    except OSError as error:
        return fail(str(InputError(error.filename, error.strerror or type(error).__name__)))
    except MemoryError:
        return fail("out of memory: give smaller inputs or fewer sessions at once")
    except Exception as error:
        if os.environ.get("MIRROR_AVATAR_DEBUG"):
            raise
        words = " ".join(str(error).split())
        click.echo(
            f"mirror-avatar: internal error: {type(error).__name__}: {words[:200]} "
            "(MIRROR_AVATAR_DEBUG=1 shows where)",
            err=True,
        )
        return 1
    return 0


def fail(problem: str) -> int:
    """Print ``problem`` as the one error line and return the bad-input exit code, 2."""
    click.echo(f"mirror-avatar: error: {problem}", err=True)
    return 2
