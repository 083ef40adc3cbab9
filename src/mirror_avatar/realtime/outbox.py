"""What a server sends one page: an outbox that a slow or stalled page cannot make wait.

Every message to a page goes through its `Outbox`, sent in order by one task of its own, so
nothing that produces messages - the clock, the receive loop - ever waits for a page. Control
messages (countdown, end...) are all delivered; of the frames only the newest undelivered one
is kept (`Outbox.superseded` counts the others), so a page that reads slowly sees the present,
not a growing backlog. Underneath, a `Peer` sends each message within ``send_timeout``
seconds, or gives the page up: a page that stopped reading has its socket aborted.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
import logging
from collections.abc import Callable
from typing import Any

from starlette.websockets import WebSocket, WebSocketDisconnect

from mirror_avatar.files.atomic import json_safe
from mirror_avatar.realtime.transport import abort_transport, stop_reading

logger = logging.getLogger(__name__)

CONTROL_BACKLOG = 64
"""Most control messages waiting for one page (the oldest are dropped beyond)."""


def encode_message(message: dict[str, Any]) -> str:
    """Encode a message to a page as strict JSON (NaN as null)."""
    return json.dumps(json_safe(message), allow_nan=False)


class Peer:
    """One page's WebSocket as the server sends to it: every send and close bounded in time.

    Parameters
    ----------
    websocket
        The accepted WebSocket.
    send_timeout
        Seconds a message may wait for a page that does not read.
    name
        Who the page is, for the log.
    on_stalled
        Called when the page stopped reading (its socket has been aborted).
    """

    def __init__(
        self,
        websocket: WebSocket,
        send_timeout: float,
        name: str,
        on_stalled: Callable[[], None] = lambda: None,
    ) -> None:
        self.websocket = websocket
        self.send_timeout = send_timeout
        self.name = name
        self.on_stalled = on_stalled

    async def send(self, text: str) -> None:
        """Send a text frame; a connection already gone is no error."""
        try:
            await asyncio.wait_for(self.websocket.send_text(text), self.send_timeout)
        except TimeoutError:
            logger.warning("dropping %s: it stopped reading", self.name)
            abort_transport(self.websocket)
            self.on_stalled()
        except (WebSocketDisconnect, RuntimeError, OSError):
            return

    async def close(self, code: int, reason: str, read_more: bool = True) -> None:
        """Close the connection with ``code`` unless it is closed or stopped reading.

        With ``read_more`` False (a refused or flooding client) nothing more it sends is read -
        the server would otherwise parse whatever it sends while waiting for its close reply -
        and its socket is aborted ``send_timeout`` seconds later.
        """
        with contextlib.suppress(RuntimeError, OSError, TimeoutError):
            await asyncio.wait_for(self.websocket.close(code, reason), self.send_timeout)
        if not read_more:  # after the close: the server resumes reading when it sends one
            stop_reading(self.websocket)
            abort_transport(self.websocket, self.send_timeout)


class Outbox:
    """Messages to one page, sent in order by one task (see the module docstring).

    Parameters
    ----------
    peer
        The page's connection.
    """

    def __init__(self, peer: Peer) -> None:
        self.peer = peer
        self._control: collections.deque[str | Callable[[], dict[str, Any]]] = collections.deque(
            maxlen=CONTROL_BACKLOG
        )
        self._frame: str | None = None
        self._ending: tuple[int, str, bool] | None = None
        self.superseded = 0
        self._closed = False
        self._ready = asyncio.Event()
        self.task = asyncio.get_running_loop().create_task(self._run())

    def put(self, message: dict[str, Any]) -> None:
        """Queue a control message."""
        self._control.append(encode_message(message))
        self._ready.set()

    def put_timed(self, make: Callable[[], dict[str, Any]]) -> None:
        """Queue a control message made as it is sent (one that says when it was sent)."""
        self._control.append(make)
        self._ready.set()

    def put_frame(self, message: dict[str, Any]) -> None:
        """Queue a frame, replacing an undelivered one."""
        if self._frame is not None:
            self.superseded += 1
        self._frame = encode_message(message)
        self._ready.set()

    async def _run(self) -> None:
        while not self._closed:
            await self._ready.wait()
            self._ready.clear()
            while (self._control or self._frame is not None) and not self._closed:
                if self._control:
                    message = self._control.popleft()
                    await self.peer.send(
                        message if isinstance(message, str) else encode_message(message())
                    )
                elif self._frame is not None:
                    frame, self._frame = self._frame, None
                    await self.peer.send(frame)
            if self._ending is not None:
                await self.peer.close(*self._ending)
                return

    def end(self, code: int, reason: str, read_more: bool = True) -> None:
        """Close the connection with ``code`` once the queued messages are sent."""
        self._ending = (code, reason, read_more)
        self._ready.set()

    @property
    def ending(self) -> bool:
        """Whether the connection is to be closed once the queued messages are sent."""
        return self._ending is not None

    async def ended(self) -> None:
        """Wait until the queued messages are sent and the connection closed (after `end`)."""
        await asyncio.wait([self.task])

    def close(self) -> None:
        """Stop sending.

        The task is cancelled, and told to end as well: a cancellation arriving as a send
        completes can be lost inside `asyncio.wait_for` (Python 3.11), which would leave the
        task waiting for ever once its page is gone.
        """
        self._closed = True
        self._ready.set()
        self.task.cancel()
