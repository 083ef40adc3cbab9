"""The ``mirror-avatar`` command line.

Each command lives in its own module of this package and is registered on `cli` below. Bad input
(an `InputError`, a usage error such as an unknown option, or a file the system refuses) is
printed as one line on standard error and ends the program with exit code 2; anything else that
goes wrong is one line too, with exit code 1 (``MIRROR_AVATAR_DEBUG=1`` shows the traceback).
Interrupted (Ctrl+C, SIGTERM or SIGHUP: `run` handles all three, and waits for compiling to
finish), a command stops its batch workers and exits with code 130.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from types import FrameType

import click
from numba.core.compiler_lock import global_compiler_lock

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
from mirror_avatar.cli.train import train
from mirror_avatar.errors import InputError


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
    except (click.Abort, KeyboardInterrupt):
        click.echo("mirror-avatar: aborted", err=True)
        return 130
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


INTERRUPT_RETRY = 0.05
"""Seconds after which an interruption that arrived while compiling is delivered again."""


def interrupt(signum: int, frame: FrameType | None) -> None:
    """Signal handler: stop the program as Ctrl+C would, so its clean-up runs.

    Not while this thread compiles (it holds numba's compiler lock): an exception raised
    inside the compiler leaves LLVM objects half made, and the process crashes when they are
    freed. The signal is then sent again after `INTERRUPT_RETRY`, until compiling is done.
    """
    if global_compiler_lock.is_locked():
        again = threading.Timer(INTERRUPT_RETRY, os.kill, (os.getpid(), signum))
        again.daemon = True
        again.start()
        return
    raise KeyboardInterrupt(signal.Signals(signum).name)


def run() -> None:
    """Console-script entry point: `main` with the process's arguments, then exit.

    Ctrl+C, SIGTERM and SIGHUP interrupt the command (`interrupt`), so that workers are
    stopped and files being written are left whole.
    """
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, interrupt)
    sys.exit(main())
