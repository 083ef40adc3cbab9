"""The command line imports a command's module only when that command runs."""

from __future__ import annotations

import subprocess
import sys

from click.testing import CliRunner

from mirror_avatar.cli import COMMANDS, cli


def test_one_command_imports_its_module_and_no_other():
    script = (
        "import sys\n"
        "from mirror_avatar.cli import main\n"
        "assert main(['info']) == 0\n"
        "print(sorted(m for m in sys.modules if m.startswith('mirror_avatar.cli.')))\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120, check=True)  # fmt: skip
    assert done.stdout.splitlines()[-1] == "['mirror_avatar.cli.info']"


def test_help_lists_every_command_with_its_description():
    shown = CliRunner().invoke(cli, ["--help"]).output
    for name in COMMANDS:
        line = next(line for line in shown.splitlines() if line.strip().startswith(name + " "))
        assert len(line.split()) > 1, line


def test_an_unknown_command_is_a_usage_error():
    result = CliRunner().invoke(cli, ["nonsense"])
    assert result.exit_code == 2 and "No such command 'nonsense'" in result.output
