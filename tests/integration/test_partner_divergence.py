"""Diverging partners through the commands and the live server: refused in one line when the
spec is made (simulate, play), and a live trial whose avatar diverges ends saying so."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path

import pytest
from test_live_server import Live, sway

from mirror_avatar.cli import main
from mirror_avatar.players.base import Observation, Player

HKB = "hkb:a=1000,b=-1000,alpha=0,beta=0,gamma=-100,omega=100"
EXCITATOR = "excitator:a=-10,b=10,tau=0.01"


@pytest.mark.parametrize(
    ("arguments", "spec"),
    [
        (["simulate", "--leader", "bundled:slow", "--follower", EXCITATOR], EXCITATOR),
        (["group", "simulate", "--player", "hkb", "--player", HKB], HKB),
        (["play", "--avatar", HKB, "--port", "0"], HKB),
    ],
)
def test_a_diverging_spec_is_refused_in_one_line_before_anything_plays(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], arguments: list[str], spec: str
) -> None:
    out = tmp_path / "out"
    assert main([*arguments, "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip()
    assert f"{spec}: diverges: " in error and "\n" not in error, error
    assert not out.exists() or not any(out.iterdir())


class Unstable(Player):
    """An avatar that jumps to 1e9 units at its 30th step."""

    label = "unstable"

    def reset(self, seed: int | None = None) -> tuple[float, float]:
        return 0.0, 0.0

    def step(self, observation: Observation) -> tuple[float, float]:
        return (1e9 if observation.k >= 29 else 0.0), 0.0


@pytest.fixture
def live(tmp_path: Path) -> Iterator[Live]:
    with ExitStack() as stack:
        yield Live(stack, tmp_path / "recordings")


def test_a_live_trial_whose_avatar_diverges_ends_naming_it(live):
    player = live.open(live.serve(lambda mode: Unstable()))
    player.start("avatar_follows", 5.0)
    summary = player.play(sway)
    assert not summary["complete"]
    assert summary["end_reason"].startswith("player 1 (avatar): diverged at sample 30 (0.90 s)")
    assert summary["diverged"]["sample"] == 30 and summary["n_samples"] == 30
