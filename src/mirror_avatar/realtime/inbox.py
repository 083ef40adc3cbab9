"""What a page sends a server: read, rate-limited and parsed, bad messages answered and counted.

An `Inbox` reads one page's WebSocket and yields its valid messages. A message beyond the page's
rate (``rate`` per second, bursts of a second's worth) or one its parser refuses
(`mirror_avatar.realtime.messages.ProtocolError`) is *rejected*: answered with the problem, and
after ``max_rejected`` of them the page is told to go and nothing more is read from it.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Callable
from typing import Generic, TypeVar

from starlette.websockets import WebSocket

from mirror_avatar.realtime.messages import ProtocolError
from mirror_avatar.realtime.rates import TokenBucket

Message = TypeVar("Message")


class Inbox(Generic[Message]):
    """One page's incoming messages (see the module docstring).

    Parameters
    ----------
    websocket
        The page's accepted WebSocket.
    parse
        Turns a frame's text (or bytes) into a message, or raises `ProtocolError`.
    rate
        Messages per second the page may send.
    max_rejected
        Rejected messages tolerated before the page is sent away.
    answer
        Tells the page a problem (queues an ``error`` message).
    send_away
        Closes the page that sent too many bad messages.

    Attributes
    ----------
    rejected
        Messages rejected so far.
    """

    def __init__(
        self,
        websocket: WebSocket,
        parse: Callable[[str | bytes | None], Message],
        rate: float,
        max_rejected: int,
        answer: Callable[[str], None],
        send_away: Callable[[], None],
    ) -> None:
        self.websocket = websocket
        self.parse = parse
        self.rate = rate
        self.bucket = TokenBucket(rate, rate)
        self.max_rejected = max_rejected
        self.answer = answer
        self.send_away = send_away
        self.rejected = 0

    async def messages(
        self,
        idle: Callable[[], float | None] = lambda: None,
        stopped: Callable[[], bool] = lambda: False,
    ) -> AsyncIterator[Message]:
        """Yield the page's valid messages until it disconnects or is sent away.

        Parameters
        ----------
        idle
            Seconds to wait for the next message (None: for ever); asked before each.
        stopped
            Whether to stop reading; asked before each message.

        Raises
        ------
        TimeoutError
            When no message came within ``idle()`` seconds.
        """
        while not stopped():
            message = await asyncio.wait_for(self.websocket.receive(), idle())
            if message["type"] == "websocket.disconnect":
                return
            if self.bucket.take() > 0.0:
                problem = f"too many messages: at most {self.rate:g} per s"
            else:
                try:
                    parsed = self.parse(message.get("text", message.get("bytes")))
                except ProtocolError as error:
                    problem = str(error)
                else:
                    yield parsed
                    continue
            if not self.reject(problem):
                return

    def reject(self, problem: str) -> bool:
        """Answer a bad message with ``problem``; return False once the page is sent away."""
        self.rejected += 1
        if self.rejected > self.max_rejected:
            self.send_away()
            return False
        self.answer(problem)
        return True
