"""The commands that serve pages refuse a port another program holds in one line."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest

from mirror_avatar.cli import main


@pytest.fixture
def taken_port() -> Iterator[int]:
    """A loopback port another program listens on."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.listen()
        yield sock.getsockname()[1]


@pytest.mark.parametrize("command", [["lab", "--no-lsl"], ["play"]], ids=lambda c: c[0])
def test_a_taken_port_is_refused_in_one_line_naming_it_and_the_option(
    command, taken_port, tmp_path, capsys
):
    out = tmp_path / "out"
    code = main([*command, "--port", str(taken_port), "--out", str(out)])
    error = capsys.readouterr().err.strip()
    assert code == 2, error
    assert error.count("\n") == 0, error
    assert f"port {taken_port}" in error and "--port" in error, error
    assert not out.exists(), "the output folder was made for a server that cannot listen"
