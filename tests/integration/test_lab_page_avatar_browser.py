"""An avatar stepped in its person's page (``runs = "browser"``), in a real Chromium against a
real lab server: a leader's page drives a tabular cyber follower, and the recording says where it
ran and holds the positions the page stepped it to, equal to the Python player's fed the
person's positions as the page saw them (METHODS section 16). A trained follower's lag behind the
person, as the page draws them and as recorded, is measured with the avatar in the page and on
the server (printed, not asserted: it is timing)."""

from __future__ import annotations

import csv
import json
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from test_lab_browser import join, pointer_at, sway

from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.players import Player
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.specs import bundled_generator
from mirror_avatar.testing import ServerThread, seeded_avatar, smooth_motion, step_in_python
from mirror_avatar.training.avatar import Avatar
from mirror_avatar.training.imitation import train_cyber_player

pytestmark = pytest.mark.browser

TOKEN = "page-avatar-token"
BEARER = {"Authorization": f"Bearer {TOKEN}"}
TOLERANCE = 1e-9
"""Largest |recorded - Python| avatar position or velocity allowed (units, units/s)."""

SHOWN = """() => {
  window.shown = [];  // what the page draws at each animation frame: time (ms), own x, avatar x
  const sample = (now) => {
    const lab = window.mirrorLab;
    if (lab.others.has(1)) window.shown.push([now, lab.me.x, lab.others.get(1)]);
    requestAnimationFrame(sample);
  };
  requestAnimationFrame(sample);
}"""


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[ServerThread]:
    settings = LabSettings(out_dir=tmp_path / "out", token=TOKEN, countdown=1)
    with ServerThread(create_lab_app(settings)) as running:
        yield running


def dyad(spec: str, runs: str, duration: float) -> dict[str, Any]:
    """A plan: person P1 leads, avatar A1 follows, run where ``runs`` says."""
    players = [{"label": "P1", "kind": "human"},
               {"label": "A1", "kind": "avatar", "spec": spec, "runs": runs}]  # fmt: skip
    return {"condition": "leader_follower", "players": players, "leaders": [0],
            "duration": duration, "pause": 0, "max_lateness": 10.0}  # fmt: skip


def play(
    chromium: Any,
    lab: ServerThread,
    plan: dict[str, Any],
    out: Path,
    motion: Callable[[float], float] = sway,
) -> tuple[Path, np.ndarray]:
    """Play the session's one trial, P1's mouse at ``motion(t)`` (units, t in s from the start);
    return its session's folder (in ``out``) and what P1's page drew at each animation frame
    (time in s, own x, avatar x), shape (n, 3).

    ``plan`` is what creates the session: a plan, or ``{"participant": N}`` for a participant's
    run of the lab's protocol."""
    created = httpx.post(f"{lab.url}/api/sessions", json=plan, headers=BEARER)
    assert created.status_code == 201, created.text
    sid, link = created.json()["id"], created.json()["links"]["P1"]
    page = join(chromium, link)
    page.evaluate(SHOWN)
    started = httpx.post(f"{lab.url}/api/sessions/{sid}/start", json={}, headers=BEARER)
    assert started.status_code == 200, started.text
    began = time.monotonic()
    while httpx.get(f"{lab.url}/api/sessions/{sid}", headers=BEARER).json()["state"] != "finished":
        for _ in range(20):
            pointer_at(page, motion(time.monotonic() - began))
            page.wait_for_timeout(15)
    shown = np.asarray(page.evaluate("window.shown"), dtype=np.float64)
    page.context.close()
    shown[:, 0] /= 1000.0
    return out / sid, shown


def read_rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8") as file:
        return list(csv.DictReader(file))


def in_python(player: Player, seed: int, steps: list[dict[str, str]]) -> np.ndarray:
    """The player's states at ticks 0..n fed the person's positions the page stepped it from,
    their velocities (x_k - x_{k-1}) / T as the page took them, shape (n + 1, 2)."""
    assert [int(row["tick"]) for row in steps] == list(range(len(steps)))
    seen = np.array([float(row["seen"]) for row in steps[1:]])
    velocity = np.diff(seen, prepend=seen[0]) / player.period
    fed = np.append(seen, seen[-1]), np.append(velocity, 0.0)  # the last is not stepped from
    return step_in_python(player, seed, fed[0][:, None], fed[1][:, None])


def assert_recorded_as_stepped(folder: Path, player: Player) -> None:
    """The trial's record says A1 ran in the browser; the ticks its page reported equal
    ``player`` fed the person's positions as the page saw them; each sample holds its tick's."""
    metadata = json.loads((folder / "trial-01_session.json").read_text())["metadata"]
    assert [slot.get("runs") for slot in metadata["lab"]["slots"]] == [None, "browser"]
    assert metadata["players"][1]["runs"] == "browser"
    steps = read_rows(folder / "trial-01_page.csv")
    expected = in_python(player, metadata["player_seeds"][1], steps)
    reported = np.array([[float(row["x"]), float(row["v"])] for row in steps])
    assert np.max(np.abs(reported - expected)) <= TOLERANCE
    assert np.ptp(expected[:, 0]) > 0.01  # it moved
    inputs = read_rows(folder / "trial-01_inputs.csv")
    session = load_session(folder / "trial-01_session.csv")
    ticks = np.array([int(row["tick_A1"]) for row in inputs])
    recorded = np.column_stack([session.positions[1], session.velocities[1]])
    assert np.array_equal(recorded, reported[ticks])
    missing = np.array([int(row["missing_A1"]) for row in inputs])
    assert metadata["missing"] == {"A1": int(missing.sum())}
    assert np.all(missing == (np.diff(ticks, prepend=-1) == 0))


def test_an_avatar_run_in_the_page_is_recorded_as_the_page_stepped_it(chromium, lab, tmp_path):
    avatar = seeded_avatar("tabular", tmp_path)
    plan = dyad(str(tmp_path / "tabular.npz"), "browser", 4.0)
    folder, _ = play(chromium, lab, plan, tmp_path / "out")
    assert_recorded_as_stepped(folder, avatar.player("follower"))


PROTOCOL = """
title = "an avatar in the page"
seed = 3

[[blocks]]
name = "main"

[[blocks.conditions]]
name = "follow"
game = "leader_follower"
players = [
  {{ label = "P1", kind = "person" }},
  {{ label = "A1", kind = "avatar", spec = "{spec}", runs = "browser" }},
]
leaders = ["P1"]
duration = 3
pause = 0
"""


def test_a_protocol_s_avatar_runs_in_the_page_it_says(chromium, tmp_path):
    avatar = seeded_avatar("tabular", tmp_path)
    path = tmp_path / "study.toml"
    path.write_text(PROTOCOL.format(spec=tmp_path / "tabular.npz"))
    out = tmp_path / "out"
    settings = LabSettings(out_dir=out, token=TOKEN, countdown=1, protocol=load_protocol(path))
    with ServerThread(create_lab_app(settings)) as lab:
        folder, _ = play(chromium, lab, {"participant": 1}, out)
    assert_recorded_as_stepped(folder, avatar.player("follower"))


GRID = 0.005
"""Spacing of the grid the drawn positions are interpolated on (s)."""


def drawn_lag(shown: np.ndarray, longest: float = 0.6) -> float:
    """The delay (s) at which the drawn avatar best correlates with the person's drawn position.

    ``shown`` is what `play` returns; its first second is left out.
    """
    times = np.arange(shown[0, 0] + 1.0, shown[-1, 0], GRID)
    own, avatar = (np.interp(times, shown[:, 0], shown[:, c]) for c in (1, 2))
    shifts = np.arange(int(longest / GRID) + 1)
    n = times.size - shifts[-1]
    fits = [np.corrcoef(own[:n], avatar[shift : shift + n])[0, 1] for shift in shifts]
    return float(shifts[int(np.argmax(fits))] * GRID)


def recorded_lag(folder: Path) -> float:
    """The same delay (s) between the recorded person and avatar, on the samples' grid."""
    session = load_session(folder / "trial-01_session.csv")
    shown = np.column_stack([session.times, session.positions[0], session.positions[1]])
    return drawn_lag(shown)


@pytest.fixture(scope="module")
def follower(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A personal avatar whose tabular follower learned to follow (3000 sessions, about 40 s)."""
    generator = bundled_generator("slow")
    partners = [bundled_generator("fast")]
    options = {"n_sessions": 3000, "duration": 30.0, "n_jobs": 1, "progress": False}
    trained, _ = train_cyber_player(generator, partners, "follower", **options)
    folder = tmp_path_factory.mktemp("trained")
    leader = seeded_avatar("tabular", folder).player("leader")
    trained.training_ = {"role": "follower"}
    return Avatar("P01", generator, {"follower": trained, "leader": leader}).save(
        folder / "trained.npz"
    )


def wander(seconds: float, rate: float = 100.0) -> Callable[[float], float]:
    """Random smooth motion within +-0.35 units (low-passed at 0.5 Hz), the same at every call:
    a partner cannot foresee it, so a follower's best-fitting delay is its response's."""
    x = smooth_motion(np.random.default_rng(5), int(seconds * rate), rate, cutoff=0.5)
    x *= 0.35 / np.max(np.abs(x))
    return lambda t: float(np.interp(t, np.arange(x.size) / rate, x))


@pytest.mark.long
def test_the_avatar_s_lag_behind_the_person_in_the_page_and_on_the_server(
    chromium, lab, tmp_path, follower
):
    lags, duration = {}, 20.0
    for runs in ("browser", "server"):
        plan = dyad(str(follower), runs, duration)
        folder, shown = play(chromium, lab, plan, tmp_path / "out", wander(duration + 10.0))
        lags[runs] = (drawn_lag(shown), recorded_lag(folder))
    for runs, (drawn, recorded) in lags.items():
        print(f"avatar run on the {runs}: {drawn * 1000:.0f} ms behind the person as the page "
              f"draws them, {recorded * 1000:.0f} ms as recorded: "
              f"{(drawn - recorded) * 1000:+.0f} ms on the page")  # fmt: skip
