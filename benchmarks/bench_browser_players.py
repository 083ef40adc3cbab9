"""An avatar's players stepped in Chromium: load time and step time, beside the Python step.

Each kind the page steps (``lab/static/avatars.js``, METHODS section 16) is built in a fresh
page of Debian's Chromium from its message (`mirror_avatar.browser.browser_arrays`, sent as JSON
text: the load time is parsing it and building the player) and stepped for one 60 s session
(2000 control periods) against a recorded person, timed in blocks of `BLOCK` steps (the page's
clock ticks in 5 µs, cross-origin isolated); p50 and p95 are over the blocks' time per step,
the first (cold) steps included. The baseline is the same player's Python ``step`` (its
compiled kernel called from Python), timed the same way in the same run; ratio = browser p95 /
Python p95. The positions are checked equal within 1e-9 before they are timed.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from playwright.sync_api import sync_playwright

from mirror_avatar.browser import browser_arrays
from mirror_avatar.datasets import load_zhai2017
from mirror_avatar.players import Observation, Player, RecordedPlayer
from mirror_avatar.specs import bundled_generator
from mirror_avatar.testing import (
    ServerThread,
    partner_motion,
    static_app,
    step_in_page,
    step_in_python,
)
from mirror_avatar.training.imitation import make_cyber_player, make_group_cyber_player

BLOCK = 10
"""Steps timed together."""

SEED = 7


def players() -> dict[str, tuple[Player, list[int]]]:
    """Return the players timed, each with the bundled trials its neighbours replay."""
    trials = load_zhai2017()
    generator = bundled_generator("slow")
    made: dict[str, tuple[Player, list[int]]] = {"recorded": (RecordedPlayer(trials[4]), [10])}
    for agent, kind in (("tabular", "cyber"), ("dqn", "deep")):
        for role in ("follower", "leader"):
            player = make_cyber_player(role, generator, agent=agent)  # type: ignore[arg-type]
            player.initialise_policy(1)
            made[f"{kind} {role}"] = (player, [10])
        group = make_group_cyber_player(generator, agent=agent)  # type: ignore[arg-type]
        group.initialise_policy(1)
        made[f"{kind} group member (3 neighbours)"] = (group, [1, 10, 12])
    return made


def python_blocks(player: Player, positions: np.ndarray, velocities: np.ndarray) -> np.ndarray:
    """Time per step (ms) of the Python player over blocks of `BLOCK` steps."""
    player.reset(SEED)
    seen = [
        Observation(k, positions[k], velocities[k], positions[max(k - 1, 0)])
        for k in range(positions.shape[0] - 1)
    ]
    blocks = []
    for first in range(0, len(seen), BLOCK):
        block = seen[first : first + BLOCK]
        start = time.perf_counter()
        for observation in block:
            player.step(observation)
        blocks.append((time.perf_counter() - start) / len(block) * 1e3)
    return np.asarray(blocks)


def measure(chromium: Any, url: str, name: str, player: Player, rows_of: list[int]) -> list[dict]:
    trials = load_zhai2017()
    positions, velocities = partner_motion([trials[i] for i in rows_of], 2000)
    page = chromium.new_page()
    page.goto(f"{url}/")
    message = browser_arrays(player, SEED, positions.shape[0] - 1)
    states, load, blocks = step_in_page(page, message, positions, velocities, BLOCK)
    _, _, warm = step_in_page(page, message, positions, velocities, BLOCK)
    page.close()
    difference = np.max(np.abs(states - step_in_python(player, SEED, positions, velocities)))
    assert difference <= 1e-9, (name, difference)
    python = python_blocks(player, positions, velocities)
    p50, p95 = (float(p) for p in np.percentile(blocks, [50, 95]) * 1e3)
    base50, base95 = (float(p) for p in np.percentile(python, [50, 95]) * 1e3)
    return [
        {
            "name": f"{name}: load in Chromium",
            "value": round(load, 2),
            "unit": "ms",
            "note": f"JSON.parse of {len(str(message)) / 1e3:.0f} kB and build",
        },
        {
            "name": f"{name}: step in Chromium, p50",
            "value": round(p50, 2),
            "unit": "µs",
            "baseline": f"Python {base50:.2f} µs",
            "ratio": round(p50 / base50, 2),
        },
        {
            "name": f"{name}: step in Chromium, p95",
            "value": round(p95, 2),
            "unit": "µs",
            "baseline": f"Python {base95:.2f} µs",
            "ratio": round(p95 / base95, 2),
            "note": f"largest browser - Python difference {difference:.1e} over 2000 steps",
        },
        {
            "name": f"{name}: step in Chromium, p95 of a second session",
            "value": round(float(np.percentile(warm, 95)) * 1e3, 2),
            "unit": "µs",
            "baseline": f"Python {base95:.2f} µs",
            "ratio": round(float(np.percentile(warm, 95)) * 1e3 / base95, 2),
            "note": "a new player from the same message, the page's code compiled",
        },
    ]


def run(quick: bool) -> list[dict]:
    rows = []
    with ServerThread(static_app()) as server, sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path="/usr/bin/chromium")
        for name, (player, rows_of) in players().items():
            if quick and name not in ("recorded", "cyber follower", "deep follower"):
                continue
            rows += measure(chromium, server.url, name, player, rows_of)
        chromium.close()
    return rows
