import subprocess
import sys

from mirror_avatar.cli import main


def test_info_lists_versions(capsys):
    assert main(["info"]) == 0
    out = capsys.readouterr().out
    assert "mirror-avatar" in out and "numpy" in out


def test_unknown_option_is_one_line_exit_2():
    done = subprocess.run(
        [sys.executable, "-c", "from mirror_avatar.console import run; run()", "info", "--bogus"],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2
    assert done.stderr.strip().count("\n") == 0
    assert "--bogus" in done.stderr
    assert "Traceback" not in done.stderr
