"""A disk that fills up mid-trial, on a real small file system (tmpfs, mounted for the test):
the trial ends as "disk full" naming the file it could not write, with every sample it wrote,
the pages get their end message, and once space is freed the next trial starts with new files."""

from __future__ import annotations

import asyncio
import os
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from test_lab_server import DYAD, TOKEN, Page, command, create, status, stopped, welcomed

from mirror_avatar.lab.running.server import LabSettings, create_lab_app
from mirror_avatar.sessions.loading import load_session
from mirror_avatar.testing import ServerThread
from waiting import wait_for

DISK_BYTES = 256 * 1024
ROOM_BYTES = 36 * 1024
"""Space left for the first trial: its files' first pages (tmpfs takes 4 KiB pages) and a few
seconds of a dyad's samples."""


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 256 KiB tmpfs (needs the right to mount: root in the test container)."""
    mount = tmp_path / "disk"
    mount.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={DISK_BYTES}", "tmpfs", str(mount)],
        capture_output=True,
        check=False,
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


def fill(folder: Path, leave: int) -> Path:
    """Write a file taking all the space of ``folder``'s file system but ``leave`` bytes."""
    free = shutil.disk_usage(folder).free
    filler = folder / "filler"
    filler.write_bytes(b"\0" * max(0, free - leave))
    return filler


@pytest.mark.long
def test_a_full_disk_ends_the_trial_cleanly_and_the_next_starts_with_new_files(small_disk):
    out = small_disk / "out"
    settings = LabSettings(out_dir=out, token=TOKEN, countdown=1)
    with ServerThread(create_lab_app(settings)) as lab:
        created = create(lab, DYAD | {"duration": 12.0, "trials": 2, "pause": 0.5})
        sid = created["id"]
        filler = fill(small_disk, ROOM_BYTES)
        pages = [Page(created["links"][label]) for label in ("P1", "P2")]

        async def first_trial() -> None:
            tasks = [asyncio.create_task(page.play(60.0)) for page in pages]
            await welcomed(pages)
            await asyncio.to_thread(lambda: command(lab, sid, "start").raise_for_status())
            await asyncio.to_thread(wait_for, lambda: all(p.of_type("end") for p in pages), 40.0)
            await stopped(tasks)

        asyncio.run(first_trial())
        now = status(lab, sid)
        assert now["state"] == "waiting" and now["error"].startswith("disk full")
        assert now["next_trial"] == 2
        (trial,) = now["trials"]
        full = f"disk full: cannot write {out / sid}/trial-01_"
        assert not trial["complete"] and trial["end_reason"].startswith(full)
        assert trial["end_reason"].endswith(".csv (No space left on device)")
        for page in pages:
            (end,) = page.of_type("end")
            assert end["reason"] == trial["end_reason"] and end["next_in"] is None
        session = load_session(out / sid / "trial-01_session.csv")
        seen = max(frame["k"] for frame in pages[0].of_type("frame"))
        assert 0 < seen < session.n_samples < 12 / 0.03  # every sample shown is on disk
        assert trial["n_samples"] >= seen + 1

        os.unlink(filler)
        pages = [Page(created["links"][label]) for label in ("P1", "P2")]

        async def second_trial() -> None:
            tasks = [asyncio.create_task(page.play(60.0)) for page in pages]
            await welcomed(pages)
            started = await asyncio.to_thread(command, lab, sid, "start")
            assert started.status_code == 200, started.text
            await asyncio.to_thread(wait_for, lambda: status(lab, sid)["state"] == "finished", 60)
            await stopped(tasks)

        asyncio.run(second_trial())
        second = status(lab, sid)["trials"][1]
        assert second["complete"] and second["files"][0] == "trial-02_session.csv"
        assert load_session(out / sid / "trial-02_session.csv").n_samples == round(12 / 0.03) + 1
