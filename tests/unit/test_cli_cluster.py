"""``--scheduler``: plain text beyond loopback is refused unless ``--insecure-scheduler``."""

from __future__ import annotations

from pathlib import Path

import pytest

from mirror_avatar.cli import cluster, main
from mirror_avatar.cli.cluster import check_encrypted
from mirror_avatar.common.errors import InputError


@pytest.mark.parametrize(
    "address",
    ["tcp://127.0.0.1:8786", "tcp://127.0.0.2:8786", "tcp://localhost:8786", "tcp://[::1]:8786",
     "127.0.0.1:8786", "tls://10.0.0.1:8786", "tls://scheduler.example.org:8786"],
)  # fmt: skip
def test_loopback_or_tls_addresses_are_taken(address: str) -> None:
    check_encrypted(address)


@pytest.mark.parametrize(
    "address",
    ["tcp://10.0.0.1:8786", "10.0.0.1:8786", "tcp://scheduler.example.org:8786",
     "tcp://0.0.0.0:8786", "tcp://[2001:db8::1]:8786", "ws://10.0.0.1:8786", "tcp://:8786"],
)  # fmt: skip
def test_plain_text_beyond_loopback_is_refused(address: str) -> None:
    with pytest.raises(InputError, match="tls:// with certificates or an SSH tunnel"):
        check_encrypted(address)


@pytest.fixture
def reached(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The addresses the command tried to connect to (each attempt ends it in one line)."""
    addresses: list[str] = []

    def connect(address: str) -> None:
        addresses.append(address)
        raise InputError(address, "stand-in scheduler")

    monkeypatch.setattr(cluster, "check_scheduler", connect)
    return addresses


def _train(tmp_path: Path, *options: str) -> int:
    return main(["train", "--target", "bundled:slow", "--partners", "bundled:fast",
                 "--sessions", "2", *options, "--out", str(tmp_path / "p.npz")])  # fmt: skip


def test_the_command_refuses_before_connecting(
    tmp_path: Path, reached: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    assert _train(tmp_path, "--scheduler", "tcp://10.0.0.1:8786") == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "--insecure-scheduler" in error, error
    assert reached == [] and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("first", [True, False])
def test_insecure_scheduler_takes_it_wherever_it_is_given(
    tmp_path: Path, reached: list[str], capsys: pytest.CaptureFixture[str], first: bool
) -> None:
    options = ["--scheduler", "tcp://10.0.0.1:8786"]
    options = ["--insecure-scheduler", *options] if first else [*options, "--insecure-scheduler"]
    assert _train(tmp_path, *options) == 2
    assert "stand-in scheduler" in capsys.readouterr().err
    assert reached == ["tcp://10.0.0.1:8786"]
