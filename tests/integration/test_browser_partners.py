"""The adaptive-control partner played live in a real browser (Playwright, Debian's Chromium)."""

from __future__ import annotations

from pathlib import Path

import pytest
from browsers import assert_matches, on_the_clock
from test_browser import drive, finish, inputs_of, start_trial

from mirror_avatar.live.server import LiveSettings, create_app
from mirror_avatar.live.session import make_avatar_factory
from mirror_avatar.players import Observation
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.testing import ServerThread

pytestmark = pytest.mark.browser


@pytest.mark.long
def test_adaptive_partner_follows_the_driven_mouse(chromium, tmp_path: Path) -> None:
    factory = make_avatar_factory("adaptive")
    warm = factory("avatar_follows")  # compile its kernels before the trial, as play does
    warm.reset(seed=0)
    warm.step(Observation.of_partner(0, 0.0, 0.0, 0.0))
    settings = LiveSettings(out_dir=tmp_path, avatar_spec="adaptive", countdown=1)
    with ServerThread(create_app(settings, factory)) as server:
        page = chromium.new_page(viewport={"width": 1100, "height": 760})
        start_trial(page, server.url, "avatar_follows", 5)
        driven = drive(page, 10)
        summary = finish(page, "adaptive_follows", tmp_path)
        page.close()
    assert summary["complete"], summary.get("end_reason")
    assert summary["avatar_role"] == "follower"
    session = load_session(tmp_path / "B01" / summary["files"]["session"])
    assert_matches(on_the_clock(inputs_of(summary, tmp_path), session.positions[0]), driven)
    assert session.metadata["avatar_player"] == "AdaptivePlayer"
    metrics = summary["metrics"]
    assert metrics["mean_relative_phase"] > 0  # the person (player 0) is ahead
    assert metrics["phase_locking"] > 0.5 and metrics["rmse"] < 0.2
