"""A trial recording whose last line was torn (a full disk, a crash mid-write): its complete lines
are read and the torn one is left out with a warning naming the file and the line."""

from __future__ import annotations

import logging

import numpy as np

from mirror_avatar.sessions.loading import load_session
from mirror_avatar.sessions.session import Session


def test_a_torn_last_line_is_left_out_naming_the_file_and_line(tmp_path, caplog):
    times = np.arange(40) * 0.03
    positions = np.vstack([0.2 * np.sin(times), 0.2 * np.cos(times)])
    nothing = np.full_like(positions, np.nan)
    path = tmp_path / "trial-01_session.csv"
    Session(times, positions, np.gradient(positions, times, axis=1), nothing, nothing).save_csv(
        path
    )
    text = path.read_text()
    path.write_text(text[:-15])  # the last line cut mid-number, as a full disk leaves it
    with caplog.at_level(logging.WARNING, logger="mirror_avatar.sessions.session"):
        session = load_session(path)
    assert session.n_samples == 39
    (record,) = caplog.records
    assert record.getMessage().startswith(f"{path}: line 41 has no line end")
    caplog.clear()
    path.write_text(text)
    assert load_session(path).n_samples == 40 and not caplog.records
