"""The lab's recordings pinned: a seeded lab session and a seeded study participant, played
through the real server, record what they recorded before (`lab_recordings`)."""

from __future__ import annotations

import json
from typing import Any

from lab_recordings import RECORDED, record

MOST_FRAMES_DROPPED = 0.1
"""Share of a page's frames that may be superseded before they were sent (a busy machine)."""


def assert_pages_saw_the_same(pages: list[dict[str, Any]], pinned: list[dict[str, Any]]) -> None:
    """Each page was sent the same messages, and every frame it got is the frame pinned.

    A frame superseded before it could be sent is not there: at most `MOST_FRAMES_DROPPED`.
    """
    assert len(pages) == len(pinned)
    for page, expected in zip(pages, pinned, strict=True):
        assert page["messages"] == expected["messages"]
        frames, pinned_frames = page["frames"], expected["frames"]
        assert set(frames) <= set(pinned_frames)
        assert len(frames) >= (1 - MOST_FRAMES_DROPPED) * len(pinned_frames)
        assert {k: pinned_frames[k] for k in frames} == frames


def test_a_lab_session_and_a_study_participant_record_what_they_recorded_before(tmp_path):
    recorded = json.loads(json.dumps(record(tmp_path)))  # as the pinned file holds them
    pinned = json.loads(RECORDED.read_text())
    for kind in ("lab", "study"):
        assert recorded[kind]["files"] == pinned[kind]["files"], kind
        assert_pages_saw_the_same(recorded[kind]["pages"], pinned[kind]["pages"])
