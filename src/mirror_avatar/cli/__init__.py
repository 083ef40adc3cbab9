"""The ``mirror-avatar`` command line.

Each command lives in its own module of this package, imported when it runs (`COMMANDS`). Bad input
(an `InputError`, a usage error such as an unknown option, or a file the system refuses) is
printed as one line on standard error and ends the program with exit code 2; anything else that
goes wrong is one line too, with exit code 1 (``MIRROR_AVATAR_DEBUG=1`` shows the traceback).
A command that needs a package of an optional extra that is not installed (`OPTIONAL_MODULES`)
says in one line which extra to install, with exit code 2.
Interrupted (Ctrl+C, SIGTERM or SIGHUP, unless ignored when the program started: the console
script `mirror_avatar.console.run` handles them from its first instant, and waits for compiling
to finish), a command stops its batch workers and exits with code 130, naming the signal.
"""

from __future__ import annotations

import importlib
import os

import click

from mirror_avatar.common.errors import InputError
from mirror_avatar.common.interruptions import aborted, interrupt
from mirror_avatar.common.text import printable

__all__ = ["cli", "fail", "interrupt", "main"]


COMMANDS = (
    "avatar", "benchmark", "convert", "curriculum", "evaluate", "generator", "group", "info",
    "lab", "play", "reproduce", "signature", "simulate", "study", "train",
)  # fmt: skip
"""The commands: each is the attribute of its own name in the module ``mirror_avatar.cli.NAME``."""

OPTIONAL_MODULES = {
    "dask": "cluster", "distributed": "cluster",
    "gymnasium": "rl", "pettingzoo": "rl", "stable_baselines3": "sb3",
    "starlette": "live", "uvicorn": "live", "websockets": "live", "segno": "live", "httpx": "live",
    "pylsl": "lsl",
}  # fmt: skip
"""The top-level modules of the optional extras' packages, each with the extra that installs it."""


class CommandsOnDemand(click.Group):
    """A group that imports a command's module only when that command is asked for.

    Each command pulls in what it works with (SciPy, scikit-learn, Starlette, Dask, ...); a
    command line imports one command, so the program starts in the time that command needs.
    ``--help`` without a command imports them all, to show their one-line descriptions.
    """

    def list_commands(self, ctx: click.Context) -> list[str]:
        """Name every command, in alphabetical order."""
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        """Import and return the command ``cmd_name`` (None if there is none by that name)."""
        if cmd_name not in COMMANDS:
            return None
        module = importlib.import_module(f"{__name__}.{cmd_name}")
        command: click.Command = getattr(module, cmd_name)
        return command


@click.group(cls=CommandsOnDemand, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="mirror-avatar")
def cli() -> None:
    """Build avatars that move like a specific person and play the mirror game."""


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
        extra = missing_extra(error)
        if extra is not None:
            return fail(extra)
        words = " ".join(str(error).split())
        click.echo(
            f"mirror-avatar: internal error: {type(error).__name__}: {words[:200]} "
            "(MIRROR_AVATAR_DEBUG=1 shows where)",
            err=True,
        )
        return 1
    return 0


def missing_extra(error: BaseException) -> str | None:
    """Return the line naming the extra to install when ``error`` is one's module missing."""
    if not isinstance(error, ModuleNotFoundError) or not error.name:
        return None
    module = error.name.partition(".")[0]
    extra = OPTIONAL_MODULES.get(module)
    if extra is None:
        return None
    return f"this command needs {module}: pip install 'mirror-avatar[{extra}]'"


def fail(problem: str) -> int:
    """Print ``problem`` as the one error line and return the bad-input exit code, 2.

    Its control characters are escaped (`mirror_avatar.common.text.printable`): a file name
    quoted in it may not act on the terminal.
    """
    click.echo(f"mirror-avatar: error: {printable(problem)}", err=True)
    return 2
