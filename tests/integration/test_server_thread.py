"""The tests' live server thread stops at the end of its test, even when a handler ignores the
shutdown: a server left running would hold its sockets open into later tests."""

from __future__ import annotations

import asyncio
import time
from typing import Any

from websockets.sync.client import connect

from mirror_avatar.testing import ServerThread


async def stubborn(scope: dict[str, Any], receive: Any, send: Any) -> None:
    """An ASGI app whose WebSocket handler ignores the server's shutdown and never returns."""
    if scope["type"] == "websocket":
        await receive()
        await send({"type": "websocket.accept"})
        while True:
            await asyncio.sleep(1.0)


def test_a_server_whose_handler_never_returns_is_stopped_when_the_test_ends():
    running = ServerThread(stubborn, stop_timeout=1.0)
    with running, connect(f"ws://{running.host}:{running.port}/ws", open_timeout=30):
        began = time.monotonic()
    assert not running.thread.is_alive()
    assert time.monotonic() - began < 30.0
