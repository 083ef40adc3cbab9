"""Partners across links of different delays, in real browsers: two pages, one behind an emulated
internet of 20 ms one way, the other of 150 ms, play one trial of each handling a protocol
declares (`partner_view`), their pointers swaying smoothly.

- ``as_arrives``: each page draws its partner a downlink after the sample, so the far page sees
  about 130 ms later than the near one;
- ``equalised`` (local lag to the slowest link): both draw each sample at the same time after
  it. Both means within `EQUAL_MS`: what remains between the pages is the server's own time
  from stamping a sample to sending it and the proxy's from receiving a chunk to delivering it
  (the far page draws as its frames arrive, the near one at the due time on its clock), and the
  two page clocks' offsets (the proxy's legs are equal, so each is within a millisecond); each
  draw also waits for the next animation frame (0 to 16.7 ms at 60 Hz), alike on both pages,
  so over hundreds of draws the means differ by a few ms;
- ``predicted`` (dead reckoning over each page's own one-way delay): the position drawn is
  nearer the partner's recorded position at the time it is drawn than the sample it was
  predicted from, draw by draw (a comparison within the trial: across trials, a machine whose
  load changes changes the delays, and so the errors, more than prediction does).

Every number is read back from what the run recorded: the view files, the sidecars, the study
table.
"""

from __future__ import annotations

import json
import time
from typing import Any
from urllib.parse import urlsplit

import numpy as np
import pandas as pd
import pytest
from test_lab_browser import join
from test_lab_server import BEARER, command, status
from test_lab_study import create_participant, protocol_lab

from mirror_avatar.cli import main
from mirror_avatar.remote.network import parse_network
from mirror_avatar.remote.proxy import ProxyThread
from mirror_avatar.sessions.loading import load_session
from waiting import wait_for

pytestmark = [pytest.mark.browser, pytest.mark.realtime]

HANDLINGS = ("as_arrives", "equalised", "predicted")
ONE_WAY_MS = {"P1": 20.0, "P2": 150.0}
EQUAL_MS = 10.0
"""Largest difference of the two pages' mean drawn delays when equalised (see the docstring)."""


def protocol() -> str:
    conditions = "".join(
        f"""
[[blocks.conditions]]
name = "{handling}"
game = "joint"
players = [{{ label = "P1", kind = "person" }}, {{ label = "P2", kind = "person" }}]
partner_view = "{handling}"
trials = 1
duration = 8
pause = 1
"""
        for handling in HANDLINGS
    )
    return f'title = "partner views"\nseed = 5\n\n[[blocks]]\nname = "views"\n{conditions}'


SWAYING = """([t0, phase]) => {
  const field = document.getElementById("field");
  setInterval(() => {
    const x = 0.3 * Math.sin(2 * Math.PI * 0.4 * (Date.now() / 1000 - t0) + phase);
    const box = field.getBoundingClientRect();
    const clientX = box.left + box.width * (0.05 + 0.9 * (x + 0.5));
    field.dispatchEvent(new PointerEvent("pointermove", { clientX, clientY: box.top + 100 }));
  }, 4);
}"""
"""A page's pointer swaying at 0.4 Hz, 0.3 units, moved by the page itself."""


@pytest.mark.long
def test_equalised_views_are_drawn_equally_late_and_predicted_ones_nearer(chromium, tmp_path):
    (tmp_path / "study.toml").write_text(protocol())
    with protocol_lab(tmp_path / "study.toml") as lab:
        created = create_participant(lab.url, 0, BEARER)
        pages: dict[str, Any] = {}
        target = ("127.0.0.1", lab.port)
        with (
            ProxyThread(parse_network("20"), target, tmp_path / "p1.csv", 1) as near,
            ProxyThread(parse_network("150"), target, tmp_path / "p2.csv", 2) as far,
        ):
            for label, proxy in (("P1", near), ("P2", far)):
                pages[label] = join(chromium, proxy.url + urlsplit(created["links"][label]).path)
            t0 = time.time()
            for phase, page in enumerate(pages.values()):
                page.evaluate(SWAYING, [t0, 1.5 * phase])
            pages["P2"].wait_for_timeout(3000)  # each page's clock known (100 exchanges, 2 s)
            assert command(lab, created["id"], "start").status_code == 200
            wait_for(lambda: status(lab, created["id"])["state"] == "finished", 120.0, "the run")
            for page in pages.values():
                page.context.close()
    out = tmp_path / "out" / "study-p000"
    views, unpredicted = {}, {}
    for n, handling in enumerate(HANDLINGS, start=1):
        metadata = json.loads((out / f"trial-{n:02d}_session.json").read_text())["metadata"]
        assert metadata["lab"]["protocol_condition"] == handling
        drawn = pd.read_csv(out / metadata["files"]["view"])
        times = pd.read_csv(out / f"trial-{n:02d}_inputs.csv").clock_s.to_numpy()
        recorded = load_session(out / f"trial-{n:02d}_session.csv").positions
        for k, label in enumerate(ONE_WAY_MS):
            view = metadata["pages"][label]["view"]
            mine = drawn[drawn.label == label]
            # of 267 frames, those superseded before an animation frame drew them are not drawn
            assert view["frames"] == len(mine) > 80
            delays = (mine.shown_s - mine.sample_s) * 1000.0
            assert view["delay_ms"]["mean"] == pytest.approx(delays.mean(), abs=0.01)
            partner = recorded[1 - k]  # the partner's recorded positions, on the clock's times
            there = np.interp(mine.shown_s, times, partner)
            rms = np.sqrt(np.mean((mine.x - there) ** 2))
            assert view["error_rms"] == pytest.approx(rms, abs=1e-4)
            sampled = np.interp(mine.sample_s, times, partner)  # what it was predicted from
            unpredicted[handling, label] = float(np.sqrt(np.mean((sampled - there) ** 2)))
            views[handling, label] = view
    summary = {key: (v["delay_ms"]["mean"], v["delay_ms"]["p95"], v["error_rms"], unpredicted[key])
               for key, v in views.items()}  # fmt: skip
    print(json.dumps({f"{h} {label}": value for (h, label), value in summary.items()}))

    def mean(handling: str, label: str) -> float:
        return float(views[handling, label]["delay_ms"]["mean"])

    assert mean("as_arrives", "P2") - mean("as_arrives", "P1") > 100.0  # 150 - 20 ms apart
    assert mean("as_arrives", "P1") >= ONE_WAY_MS["P1"]
    assert abs(mean("equalised", "P2") - mean("equalised", "P1")) < EQUAL_MS
    assert mean("equalised", "P1") >= ONE_WAY_MS["P2"]  # held to the slowest link
    for label in ONE_WAY_MS:
        assert views["as_arrives", label]["error_rms"] == pytest.approx(
            unpredicted["as_arrives", label], abs=1e-4
        )  # drawn as sampled
        assert views["predicted", label]["error_rms"] < unpredicted["predicted", label]

    table = tmp_path / "table"
    assert main(["study", "table", str(out), "--out", str(table)]) == 0
    rows = pd.read_csv(table / "study.csv")
    for (handling, label), view in views.items():
        (row,) = rows[(rows.condition == handling) & (rows.person == label)].itertuples()
        assert row.page_view_delay_ms == pytest.approx(view["delay_ms"]["mean"])
        assert row.page_view_delay_p95_ms == pytest.approx(view["delay_ms"]["p95"])
        assert row.page_view_error_rms == pytest.approx(view["error_rms"])
