"""A protocol whose avatar spec cannot play is refused by the real lab server's console when it is
loaded (400, one line naming the condition and the spec), and nothing is kept of it."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest
from test_lab_server import BEARER, TOKEN

from mirror_avatar.lab.server import LabSettings, create_lab_app
from mirror_avatar.testing import ServerThread

PROTOCOL = """
title = "one dyad"
seed = 1

[[blocks]]
name = "main"

[[blocks.conditions]]
name = "hard"
game = "leader_follower"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "A1", kind = "avatar", spec = "{spec}" }},
]
leaders = ["P1"]
"""


@pytest.mark.parametrize(
    ("spec", "problem"),
    [
        ("adaptive:cp=nan", "cp must be a number in ASCII decimals (e.g. 0.5 or 2e-3), not 'nan'"),
        ("kuramoto:k=inf", "unknown parameter 'k'"),
        ("/etc/passwd", "unknown extension"),
        ("excitator:a=-10,b=10,tau=0.01", "diverges: 0.06 s into a dry run"),
    ],
)
def test_the_console_refuses_a_protocol_whose_avatar_cannot_play(tmp_path: Path, spec, problem):
    settings = LabSettings(out_dir=tmp_path / "out", token=TOKEN, countdown=1)
    with ServerThread(create_lab_app(settings)) as lab:
        text = PROTOCOL.format(spec=spec)
        answer = httpx.post(
            f"{lab.url}/api/protocol", json={"name": "s.toml", "text": text}, headers=BEARER
        )
        listing = httpx.get(f"{lab.url}/api/sessions", headers=BEARER).json()
    assert answer.status_code == 400
    error = answer.json()["error"]
    where = "s.toml: blocks[0].conditions[0].players[1].spec: condition 'hard': "
    assert error.startswith(f"{where}{spec}: ") and problem in error and "\n" not in error, error
    assert "protocol" not in listing and not (tmp_path / "out" / "protocols").exists()
