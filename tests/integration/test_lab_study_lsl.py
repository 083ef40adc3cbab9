"""A study session's LSL outlet over loopback, read back with real pylsl inlets: one stream for
the participant's whole run, a channel per player label (NaN outside its conditions), samples on
the LSL clock, markers for each condition, trial and perturbation."""

from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from test_lab_server import BEARER, TOKEN, Page
from test_lab_study import play_to_the_end

from mirror_avatar.lab.design.protocol import load_protocol
from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.testing import ServerThread

pytestmark = pytest.mark.realtime

pylsl = pytest.importorskip("pylsl")

PROTOCOL = """
title = "two conditions"
seed = 5

[[blocks]]
name = "dyads"

[[blocks.conditions]]
name = "follow"
game = "leader_follower"
players = [
  { label = "P1", kind = "person" },
  { label = "A1", kind = "avatar", spec = "bundled:slow" },
]
leaders = ["P1"]
duration = 3
pause = 0.5
perturb = [{ at = 1.5, player = "A1", set = "leader" }]

[[blocks.conditions]]
name = "together"
game = "joint"
players = [
  { label = "P1", kind = "person" },
  { label = "A2", kind = "avatar", spec = "hkb" },
]
duration = 2
pause = 0.5
"""


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[ServerThread]:
    path = tmp_path / "dyads.toml"
    path.write_text(PROTOCOL)
    # A tick of this busy test process may take long; ending the trial for it is not tested here.
    settings = LabSettings(
        out_dir=tmp_path / "out",
        token=TOKEN,
        countdown=1,
        lsl=True,
        protocol=load_protocol(path),
        max_tick=10.0,
    )
    with ServerThread(create_lab_app(settings)) as running:
        yield running


def open_inlet(source_id: str, **options: Any) -> Any:
    (info,) = pylsl.resolve_byprop("source_id", source_id, timeout=5)
    inlet = pylsl.StreamInlet(info, **options)
    inlet.open_stream(timeout=5)
    return inlet


def channels(inlet: Any) -> list[tuple[str, str, str]]:
    channel = inlet.info().desc().child("channels").child("channel")
    found = []
    while not channel.empty():
        found.append(tuple(channel.child_value(key) for key in ("label", "kind", "role")))
        channel = channel.next_sibling()
    return found


def pull_all(inlet: Any, samples: list[Any], stamps: list[float]) -> tuple[list[Any], list[float]]:
    """Pull every sample left (a first pull must come while the stream lives: see DESIGN)."""
    while True:
        chunk, times = inlet.pull_chunk(timeout=1.0)
        if not chunk:
            return samples, stamps
        samples += chunk
        stamps += times


def test_a_study_run_publishes_one_outlet_across_its_conditions(lab, tmp_path):
    created = httpx.post(f"{lab.url}/api/sessions", json={"participant": 0}, headers=BEARER)
    assert created.status_code == 201, created.text
    sid = created.json()["id"]
    inlet = open_inlet(f"mirror-avatar-{sid}", max_buflen=60)
    correction = inlet.time_correction(timeout=5)  # it would wait forever once the stream ends
    markers = open_inlet(f"mirror-avatar-{sid}-markers")
    pulled = [inlet.pull_chunk(timeout=0.0), markers.pull_chunk(timeout=0.0)]
    assert inlet.info().name() == f"mirror-avatar {sid}"
    assert inlet.info().channel_count() == 3
    assert channels(inlet) == [
        ("P1", "human", "leader/joint"),
        ("A1", "avatar", "follower"),
        ("A2", "avatar", "joint"),
    ]
    page = Page(created.json()["links"]["P1"])
    play_to_the_end(lab, sid, [page], 40.0)
    samples, stamps = pull_all(inlet, *pulled[0])
    folder = tmp_path / "out" / sid
    trials = [load_session(folder / f"trial-{n:02d}_session.csv") for n in (1, 2)]
    clocks = []
    for n in (1, 2):
        with (folder / f"trial-{n:02d}_inputs.csv").open() as file:
            clocks.append([float(row["clock_s"]) for row in csv.DictReader(file)])
    first, second = trials[0].n_samples, trials[1].n_samples
    assert (first, second) == (101, 68) and len(samples) == first + second
    published = np.asarray(samples).T
    np.testing.assert_array_equal(published[:2, :first], trials[0].positions)
    assert np.all(np.isnan(published[2, :first]))
    np.testing.assert_array_equal(published[[0, 2], first:], trials[1].positions)
    assert np.all(np.isnan(published[1, first:]))
    # Stamped on the LSL clock: each sample's stamp is the clock time its trial recorded.
    np.testing.assert_allclose(np.asarray(stamps) + correction, clocks[0] + clocks[1], atol=1e-3)
    events, times = pull_all(markers, *pulled[1])
    assert [event for (event,) in events] == [
        "condition 'follow' of block 'dyads': P1 human leader, A1 avatar follower",
        "trial 1 start",
        "perturbation A1 role=leader",
        "trial 1 end: completed",
        "condition 'together' of block 'dyads': P1 human joint, A2 avatar joint",
        "trial 2 start",
        "trial 2 end: completed",
    ]
    marked = np.asarray(times) + correction
    expected = [clocks[0][0], clocks[0][50], clocks[0][-1], clocks[1][0], clocks[1][-1]]
    np.testing.assert_allclose(marked[[1, 2, 3, 5, 6]], expected, atol=1e-3)
    assert marked[0] < marked[1] and marked[3] < marked[4] < marked[5]
