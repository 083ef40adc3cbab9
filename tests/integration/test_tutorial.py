"""The tutorial's commands: each names a real command and its options, and all of them run."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import click
import pytest

from mirror_avatar.cli import cli

TUTORIAL = Path(__file__).parents[2] / "docs" / "tutorial.md"
SKIP = "<!-- not run"


def shell_blocks() -> list[str]:
    """Return the tutorial's ``sh`` blocks that it says run (those not marked not run)."""
    text = TUTORIAL.read_text(encoding="utf-8")
    blocks = []
    for found in re.finditer(r"```sh\n(.*?)```", text, re.DOTALL):
        before = text[: found.start()].rstrip().splitlines()[-1]
        if not before.startswith(SKIP):
            blocks.append(found.group(1))
    return blocks


def commands() -> list[list[str]]:
    """Return every ``mirror-avatar`` command line of the blocks that run, as arguments."""
    lines = "\n".join(shell_blocks()).splitlines()
    return [shlex.split(line)[1:] for line in lines if line.startswith("mirror-avatar ")]


def test_the_tutorial_runs_commands_from_install_to_report():
    names = [" ".join(arguments[:2]) for arguments in commands()]
    assert names[0].startswith("generator fit")
    assert names[-1] == "study report"


@pytest.mark.parametrize("arguments", commands(), ids=lambda a: " ".join(a[:2]))
def test_each_tutorial_command_and_option_exists(arguments):
    command: click.Command = cli
    words = list(arguments)
    while isinstance(command, click.Group) and words:
        found = command.get_command(click.Context(command), words[0])
        if found is None:
            break
        command, words = found, words[1:]
    declared = {name for parameter in command.params for name in parameter.opts}
    used = {word.split("=")[0] for word in words if word.startswith("--")}
    assert used <= declared, f"{' '.join(arguments)}: no option {used - declared}"


@pytest.mark.slow
def test_the_tutorial_runs_as_written(tmp_path):
    environment = {
        **os.environ,
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
    }
    for block in shell_blocks():
        result = subprocess.run(
            ["bash", "-euo", "pipefail", "-c", block], cwd=tmp_path, env=environment,
            capture_output=True, text=True, check=False, timeout=1800,
        )  # fmt: skip
        assert result.returncode == 0, f"{block}\n{result.stdout[-2000:]}\n{result.stderr[-2000:]}"
    assert (tmp_path / "P01.html").is_file()
    assert (tmp_path / "evaluation" / "report.html").is_file()
    assert (tmp_path / "report" / "report.html").is_file()
