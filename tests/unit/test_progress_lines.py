"""Progress off a terminal: a plain line at each tenth of the work, and none where silenced."""

from __future__ import annotations

import pytest

from mirror_avatar.common.progress import progress_bar, silenced


def test_a_line_comes_at_each_tenth_of_the_work(capsys: pytest.CaptureFixture[str]) -> None:
    with progress_bar(20, "training", "session") as bar:
        for _ in range(20):
            bar.update()
    lines = capsys.readouterr().err.splitlines()
    assert [line.split(",")[0] for line in lines] == [
        f"training: {k}/20 sessions ({5 * k} %)" for k in range(2, 21, 2)
    ]
    assert all(" elapsed, about " in line and line.endswith(" left") for line in lines)


def test_without_a_total_a_line_comes_at_each_doubling(capsys: pytest.CaptureFixture[str]) -> None:
    with progress_bar(None, "reading", "trial") as bar:
        for _ in range(9):
            bar.update()
    lines = capsys.readouterr().err.splitlines()
    assert [line.split(",")[0] for line in lines] == [
        "reading: 1 trial",
        "reading: 2 trials",
        "reading: 4 trials",
        "reading: 8 trials",
    ]


def test_silenced_work_shows_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    with silenced(), progress_bar(20, "warming up") as bar:
        bar.update(20)
    assert capsys.readouterr().err == ""
