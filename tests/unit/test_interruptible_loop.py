"""An event loop run by `run_interruptible`: an interruption cancels its coroutine cleanly."""

from __future__ import annotations

import asyncio
import os
import signal
from collections.abc import Iterator

import pytest

from mirror_avatar.common.interruptions import interrupt, run_interruptible


@pytest.fixture
def interrupting() -> Iterator[None]:
    """SIGTERM handled by `interrupt`, as the console script installs it."""
    previous = signal.signal(signal.SIGTERM, interrupt)
    yield
    signal.signal(signal.SIGTERM, previous)


def test_an_interruption_cancels_the_coroutine_and_names_the_signal(interrupting):
    unwound = []

    async def play() -> None:
        pages = [asyncio.create_task(asyncio.sleep(3600)) for _ in range(2)]
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            await asyncio.wait(pages)
        finally:
            for page in pages:
                page.cancel()
            await asyncio.gather(*pages, return_exceptions=True)
            unwound.append(True)

    with pytest.raises(KeyboardInterrupt, match="SIGTERM"):
        run_interruptible(play())
    assert unwound == [True]
    assert signal.getsignal(signal.SIGTERM) is interrupt


def test_a_coroutine_left_alone_returns_its_result(interrupting):
    async def answer() -> int:
        await asyncio.sleep(0)
        return 42

    assert run_interruptible(answer()) == 42
