"""The live game in a real browser: Playwright driving Debian's Chromium against a real server.

In CI (``CI=true``) these tests fail when Chromium is missing; elsewhere they skip.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import psutil
import pytest
from browsers import ARGS, CHROMIUM, SCREENSHOTS, assert_matches, chromium_mains, on_the_clock

from mirror_avatar.live.server import LiveSettings, create_app
from mirror_avatar.live.session import make_avatar_factory
from mirror_avatar.players import Observation
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.testing import ServerThread
from mirror_avatar.training.avatar import load_avatar
from waiting import wait_for

pytestmark = pytest.mark.browser


def sway(t: Any) -> Any:
    """The driven pointer trajectory (units): a 0.4 Hz sine of amplitude 0.3."""
    return 0.3 * np.sin(2 * np.pi * 0.4 * t)


@pytest.fixture(scope="module")
def avatar_factory():
    """The default avatar, built once first (as ``mirror-avatar play`` does) so that fitting the
    bundled generator and compiling the engine do not delay the first trial."""
    factory = make_avatar_factory()
    avatar = factory("avatar_follows")
    avatar.reset(seed=0)
    avatar.step(Observation.of_partner(0, 0.0, 0.0, 0.0))
    return factory


@pytest.fixture
def server(tmp_path: Path, avatar_factory) -> Iterator[ServerThread]:
    settings = LiveSettings(out_dir=tmp_path, avatar_spec="bundled:slow", countdown=1)
    with ServerThread(create_app(settings, avatar_factory)) as running:
        yield running


def start_trial(page: Any, url: str, mode: str, duration: float) -> None:
    page.goto(url)
    page.wait_for_function("window.mirrorGame && window.mirrorGame.phase === 'idle'")
    page.fill("#participant", "B01")
    page.select_option("#mode", mode)
    page.fill("#duration", str(duration))
    page.click("#start")
    box = page.locator("#track").bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.wait_for_function("window.mirrorGame.phase === 'running'", timeout=60_000)


def drive(page: Any, seconds: float) -> np.ndarray:
    """Move the mouse over the track along `sway` for ``seconds`` or until the trial ends.

    Returns
    -------
    ndarray
        The (time, position) pairs driven, shape (n, 2), each move's time on the monotonic
        clock (`time.monotonic`, s), as the trial's inputs file records its samples'.
    """
    box = page.locator("#track").bounding_box()
    y = box["y"] + box["height"] / 2
    began = time.monotonic()
    driven = []
    while (t := time.monotonic() - began) < seconds:
        x = float(sway(t))
        page.mouse.move(box["x"] + (x + 0.5) * box["width"], y)
        driven.append((began + t, x))
        if len(driven) % 15 == 0 and page.evaluate("window.mirrorGame.phase") != "running":
            break
        time.sleep(max(0.0, began + len(driven) / 60 - time.monotonic()))
    return np.asarray(driven)


def inputs_of(summary: dict[str, Any], tmp_path: Path) -> Path:
    """The inputs file of participant B01's trial whose summary (or sidecar metadata) is given."""
    return tmp_path / "B01" / summary["files"]["inputs"]


def finish(page: Any, name: str, tmp_path: Path) -> dict[str, Any]:
    page.wait_for_selector("#results:not([hidden])", timeout=60_000)
    summary = page.evaluate("window.mirrorGame.summary")
    page.screenshot(path=tmp_path / f"{name}.png", full_page=True)
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    shutil.copy(tmp_path / f"{name}.png", SCREENSHOTS / f"{name}.png")
    return summary


PIXELS_OF = """([id, rgb]) => {
  const canvas = document.getElementById(id);
  const data = canvas.getContext("2d").getImageData(0, 0, canvas.width, canvas.height).data;
  let n = 0;
  for (let i = 0; i < data.length; i += 4) {
    const near = Math.abs(data[i] - rgb[0]) + Math.abs(data[i + 1] - rgb[1]) +
      Math.abs(data[i + 2] - rgb[2]) < 40;
    if (near && data[i + 3] > 200) n += 1;
  }
  return n;
}"""
"""Count a canvas's opaque pixels within a small distance of a colour."""

PERSON_RGB, AVATAR_RGB, PHASE_RGB = (37, 99, 235), (234, 122, 18), (75, 85, 99)
"""The line colours of game.js: the person, the avatar, the relative phase."""


def drawn(page: Any, canvas: str, rgb: tuple[int, int, int]) -> int:
    """Pixels of ``canvas`` drawn in ``rgb`` (a line of the results screen's figures)."""
    return int(page.evaluate(PIXELS_OF, [canvas, list(rgb)]))


def assert_legends(page: Any, avatar: bool) -> None:
    """Each figure of the results names its lines: you, the avatar (with one), the phase."""
    for figure in ("plot", "positions"):
        caption = page.locator(f"figure:has(#{figure}) figcaption")
        assert caption.locator(".key:not(.avatar-key)").inner_text() == "You"
        assert caption.locator(".avatar-key").is_visible() == avatar
    if avatar:
        assert "You − avatar" in page.locator("#phase-figure figcaption").inner_text()


def load_csv(path: Path) -> np.ndarray:
    assert path.read_text().splitlines()[0] == "time,position"
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def test_solo_trial_records_the_driven_trajectory(chromium, server, tmp_path):
    page = chromium.new_page(viewport={"width": 1100, "height": 760})
    start_trial(page, server.url, "solo", 4)
    driven = drive(page, 10)
    summary = finish(page, "solo", tmp_path)
    assert summary["complete"], summary.get("end_reason")
    assert summary["mode"] == "solo"
    data = load_csv(tmp_path / "B01" / summary["files"]["person"])
    assert data.shape[0] == summary["n_samples"] == round(4 / 0.03) + 1
    assert_matches(on_the_clock(inputs_of(summary, tmp_path), data[:, 1]), driven)
    assert page.locator("#metrics").inner_text().count("units/s") == 1
    assert drawn(page, "positions", PERSON_RGB) > 200 and drawn(page, "positions", AVATAR_RGB) == 0
    assert page.locator("#phase-figure").is_hidden()
    assert_legends(page, avatar=False)
    page.close()


TRACE_FRAMES = """() => {
  // After each of the page's own frames (animation frame callbacks run in the order they were
  // asked for), the frame's time (s) and the dot's position: the page's clock, not the server's.
  window.frames = [];
  const look = (now) => {
    window.frames.push([now / 1000, window.mirrorGame.x]);
    requestAnimationFrame(look);
  };
  requestAnimationFrame(look);
}"""


def test_keyboard_moves_the_dot_at_a_constant_speed(chromium, server, tmp_path):
    """The dot moves at KEY_SPEED on the page's clock (the server samples whatever position
    last arrived, as irregularly as a busy machine delivers it), and the server records the
    position the page ended at."""
    page = chromium.new_page()
    start_trial(page, server.url, "solo", 2)
    page.evaluate(TRACE_FRAMES)
    page.keyboard.down("ArrowRight")
    time.sleep(0.5)
    page.keyboard.up("ArrowRight")
    summary = finish(page, "keyboard", tmp_path)
    step = np.diff(np.asarray(page.evaluate("window.frames")), axis=0)
    moving = (step[:, 1] > 0) & (step[:, 0] <= 0.1)  # game.js moves at most 0.1 s per frame
    assert moving.sum() >= 3
    speed = step[moving, 1] / step[moving, 0]
    assert np.median(speed) == pytest.approx(0.8, rel=0.01)  # KEY_SPEED in game.js, units/s
    data = load_csv(tmp_path / "B01" / summary["files"]["person"])
    assert data[-1, 1] == pytest.approx(page.evaluate("window.mirrorGame.x"), abs=1e-6)
    page.close()


def test_avatar_follows_the_driven_mouse(chromium, server, tmp_path):
    page = chromium.new_page(viewport={"width": 1100, "height": 760})
    start_trial(page, server.url, "avatar_follows", 5)
    driven = drive(page, 10)
    summary = finish(page, "avatar_follows", tmp_path)
    assert summary["complete"], summary.get("end_reason")
    assert summary["avatar_role"] == "follower"
    session = load_session(tmp_path / "B01" / summary["files"]["session"])
    assert_matches(on_the_clock(inputs_of(summary, tmp_path), session.positions[0]), driven)
    metrics = summary["metrics"]
    assert metrics["mean_relative_phase"] > 0  # the person (player 0) is ahead
    assert metrics["phase_locking"] > 0.5 and metrics["rmse"] < 0.2
    assert summary["round_trip_ms"]["n"] > 100 and summary["round_trip_ms"]["median"] < 100
    table = page.locator("#metrics").inner_text()
    for label in ("RMSE", "CV", "Relative phase", "Round trip"):
        assert label in table
    traces = summary["traces"]
    step = int(np.ceil(session.n_samples / 600))
    np.testing.assert_allclose(traces["positions"], session.positions[:, ::step])
    assert len(traces["relative_phase"]) == len(traces["times"])
    assert drawn(page, "positions", PERSON_RGB) > 200 and drawn(page, "positions", AVATAR_RGB) > 200
    assert page.locator("#phase-figure").is_visible() and drawn(page, "phase", PHASE_RGB) > 200
    assert_legends(page, avatar=True)
    page.close()


def test_killing_the_browser_mid_trial_leaves_an_incomplete_trial(playwright, server, tmp_path):
    before = chromium_mains()
    browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
    (main,) = chromium_mains() - before
    page = browser.new_page()
    start_trial(page, server.url, "avatar_follows", 30)
    driven = drive(page, 1.5)
    os.kill(main, signal.SIGKILL)
    with contextlib.suppress(psutil.NoSuchProcess):  # already reaped
        psutil.Process(main).wait(10)
    sidecar = next((tmp_path / "B01").glob("*_session.json"))
    wait_for(lambda: "ended_utc" in json.loads(sidecar.read_text())["metadata"])
    record = json.loads(sidecar.read_text())["metadata"]
    assert not record["complete"] and record["end_reason"] in (
        "connection closed",
        "the browser stopped sending",
    )
    session = load_session(tmp_path / "B01" / record["files"]["session"])
    assert session.n_samples == json.loads(sidecar.read_text())["n_samples"] > 20
    assert session.metadata["complete"] is False
    assert_matches(on_the_clock(inputs_of(record, tmp_path), session.positions[0]), driven)


def test_server_keeps_serving_and_tabs_can_close(chromium, server, tmp_path):
    page = chromium.new_page()
    start_trial(page, server.url, "solo", 30)
    drive(page, 0.5)
    page.close()
    other = chromium.new_page()
    start_trial(other, server.url, "joint", 2)
    drive(other, 5)
    assert finish(other, "joint", tmp_path)["complete"]
    records = [load_session(p).metadata for p in (tmp_path / "B01").glob("*_session.csv")]
    assert sorted((r["mode"], r["complete"]) for r in records) == [
        ("joint", True),
        ("solo", False),
    ]
    other.close()


def test_token_protected_server_refuses_pages_without_it(chromium, tmp_path):
    settings = LiveSettings(out_dir=tmp_path, token="letmein", countdown=0)
    with ServerThread(create_app(settings, None), host="0.0.0.0") as running:
        local = f"http://127.0.0.1:{running.port}/"
        page = chromium.new_page()
        assert page.goto(local).status == 403
        assert page.goto(local + "?token=letmein").status == 200
        page.wait_for_function("window.mirrorGame.phase === 'idle'")
        page.close()


@pytest.mark.long
def test_record_solo_trials_build_your_avatar_and_play_with_it(chromium, avatar_factory, tmp_path):
    """The whole personal-avatar loop on one page: three solo trials, "Build my avatar" (with
    its stages shown, then its verdict and card), then a trial with the avatar just built
    (small training for the test)."""
    settings = LiveSettings(out_dir=tmp_path, avatar_spec="bundled:slow", countdown=1,
                            build_sessions=(30, 1, 4))  # fmt: skip
    with ServerThread(create_app(settings, avatar_factory)) as server:
        page = chromium.new_page()
        hints = []
        for k in range(3):  # one is held out of fitting to check the avatar against
            start_trial(page, server.url, "solo", 8)
            drive(page, 9)
            finish(page, f"own-avatar-solo-{k + 1}", tmp_path)
            hints.append(page.text_content("#build-hint"))
        assert "record 1 more to build your avatar" in hints[0]
        assert "can be built, but it will not be checked against you" in hints[1]
        assert "enough to build your avatar and check it" in hints[2]
        page.click("#build")
        page.wait_for_function("window.mirrorGame.phase === 'building'")
        page.wait_for_function("window.mirrorGame.personalAvatar !== null", timeout=180_000)
        assert "Your avatar is ready (B01_avatar.npz)" in page.text_content("#status")
        verdict = page.text_content("#verdict-text")
        built = load_avatar(tmp_path / "B01" / "B01_avatar.npz")
        assert verdict == built.summary["verdict"] and "role and partner pairs" in verdict
        assert verdict.startswith("The avatar moves") and "held-out trials" in verdict
        card = page.evaluate("fetch(document.getElementById('card-link').href).then(r => r.text())")
        assert card == (tmp_path / "B01" / "B01_avatar.html").read_text()
        assert page.locator("#card-link").is_visible()
        SCREENSHOTS.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=SCREENSHOTS / "own-avatar-ready.png")
        page.select_option("#mode", "avatar_follows")
        page.fill("#duration", "4")
        page.click("#start")
        page.wait_for_function("window.mirrorGame.phase === 'running'", timeout=60_000)
        drive(page, 5)
        summary = finish(page, "own-avatar-trial", tmp_path)
        # after solo trials (no phase figure) the avatar trial's relative phase is drawn
        assert page.locator("#phase-figure").is_visible() and drawn(page, "phase", PHASE_RGB) > 200
        assert_legends(page, avatar=True)
    assert summary["complete"], summary.get("end_reason")
    assert summary["avatar"].endswith("B01_avatar.npz")
    assert summary["avatar_plays"] == "avatar B01 (follower policy)"
    assert (tmp_path / "B01" / "B01_avatar.npz").is_file()
    assert "Avatar of B01" in (tmp_path / "B01" / "B01_avatar.html").read_text()


def test_building_without_solo_trials_is_refused(chromium, server):
    page = chromium.new_page()
    page.goto(server.url)
    page.wait_for_function("window.mirrorGame && window.mirrorGame.phase === 'idle'")
    assert "record 3 or more solo trials first" in page.text_content("#build-hint")
    page.fill("#participant", "NEW1")
    page.click("#build")
    page.wait_for_function("window.mirrorGame.phase === 'idle'")
    assert "play at least 2 solo trials first (0 so far)" in page.text_content("#status")
    page.close()
