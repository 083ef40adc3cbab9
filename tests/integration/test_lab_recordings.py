"""The lab's recordings pinned: a seeded lab session and a seeded study participant, played
through the real server, record what they recorded before (`lab_recordings`), their numbers to
the rounding another machine may give (`snapshots.assert_close`)."""

from __future__ import annotations

import difflib
import json
import shutil
from typing import Any

import pytest
from lab_recordings import RECORDED, record

from snapshots import LAST_DIGIT, assert_close, perturb_file, read_snapshot

pytestmark = pytest.mark.realtime

MOST_FRAMES_DROPPED = 0.1
"""Share of a page's frames that may be superseded before they were sent (a busy machine)."""


def outline(messages: list[dict[str, Any]]) -> list[str]:
    """Return each message as one line: its type, trial, state, condition and text."""
    keys = ("type", "trial", "state", "condition", "message")
    return [" ".join(str(m[key]) for key in keys if key in m) for m in messages]


def assert_pages_saw_the_same(pages: list[dict[str, Any]], pinned: list[dict[str, Any]]) -> None:
    """Each page was sent the same messages, and every frame it got is the frame pinned.

    A frame superseded before it could be sent is not there: at most `MOST_FRAMES_DROPPED`.
    Messages that differ in number or kind are shown as a diff of their outlines.
    """
    assert len(pages) == len(pinned)
    for page, expected in zip(pages, pinned, strict=True):
        found, wanted = outline(page["messages"]), outline(expected["messages"])
        assert found == wanted, "\n".join(difflib.unified_diff(wanted, found, "pinned", "sent"))
        assert_close(page["messages"], expected["messages"], "messages")
        frames, pinned_frames = page["frames"], expected["frames"]
        assert set(frames) <= set(pinned_frames)
        assert len(frames) >= (1 - MOST_FRAMES_DROPPED) * len(pinned_frames)
        assert_close(frames, {k: pinned_frames[k] for k in frames}, "frames")


def assert_recorded_as_pinned(recorded: dict[str, Any], pinned: dict[str, Any]) -> None:
    """Assert that the recordings (as `record` returns them, keys sorted) are those pinned."""
    for kind in ("lab", "study"):
        assert_close(recorded[kind]["files"], pinned[kind]["files"], kind)
        assert_pages_saw_the_same(recorded[kind]["pages"], pinned[kind]["pages"])


@pytest.mark.long
def test_a_lab_session_and_a_study_participant_record_what_they_recorded_before(tmp_path):
    recorded = json.loads(json.dumps(record(tmp_path), sort_keys=True))  # as the file holds them
    assert_recorded_as_pinned(recorded, read_snapshot(RECORDED))


def test_the_comparison_allows_rounding_and_catches_a_change(tmp_path):
    """The pinned numbers moved by their last digit pass, moved by relative 1e-6 fail (the
    pinned recordings standing for a new one, which on this machine is the same)."""
    pinned = read_snapshot(RECORDED)
    rounded, changed = tmp_path / "rounded.json", tmp_path / "changed.json"
    for copy, factor in ((rounded, LAST_DIGIT), (changed, 1.0 + 1e-6)):
        shutil.copy(RECORDED, copy)
        perturb_file(copy, factor)
    assert read_snapshot(rounded) != pinned
    assert_recorded_as_pinned(pinned, read_snapshot(rounded))
    with pytest.raises(AssertionError):
        assert_recorded_as_pinned(pinned, read_snapshot(changed))
