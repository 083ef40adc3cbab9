"""The emulated internet as a TCP proxy on loopback between pages and a server.

`EmulatedInternet` listens on a loopback port and, for every connection it accepts, opens one to
the target and carries each direction as a *lane*: a reader takes each chunk as the socket gives
it, draws its delay and plans its delivery (`mirror_avatar.remote.network.due_time`); a writer
delivers the chunks in order, each at its time, and writes its row of the truth
(`mirror_avatar.remote.truth`). The end of a stream is carried the same way (a half close).
`ProxyThread` runs one on an event loop of its own, for the pilot and the tests.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mirror_avatar.remote.network import Network, due_time, lane_rng
from mirror_avatar.remote.truth import Chunk, TruthLog, request_line, write_companion

LOOPBACK = "127.0.0.1"
"""Where the proxy listens: this machine only."""

CHUNK_BYTES = 65_536
"""Most bytes read from a socket at once (one chunk)."""

START_TIMEOUT = 10.0
"""Seconds a `ProxyThread` may take to listen."""


def now_s() -> float:
    """Return the monotonic clock (s, from `time.monotonic_ns`)."""
    return time.monotonic_ns() / 1e9


@dataclass
class Lane:
    """One connection's one direction: what it has planned and delivered.

    ``previous_s`` is when the last planned chunk is due (s after the proxy started).
    """

    connection: int
    direction: str
    rng: np.random.Generator
    previous_s: float = -np.inf
    count: int = 0
    queue: asyncio.Queue[tuple[bytes, Chunk]] = field(default_factory=asyncio.Queue)


class EmulatedInternet:
    """A TCP proxy that delays every chunk as ``network`` declares and logs the truth.

    Parameters
    ----------
    network
        The delays and stalls.
    target
        Host and port of the server the pages reach through it.
    log
        The truth log (CSV; its JSON companion beside it).
    seed
        The seed of every lane's delays (`mirror_avatar.remote.network.lane_rng`).
    listening
        A socket bound on loopback to listen on (default: one on any free port).
    """

    def __init__(
        self,
        network: Network,
        target: tuple[str, int],
        log: Path,
        seed: int,
        listening: socket.socket | None = None,
    ) -> None:
        self.network = network
        self.target = target
        self.log_path = log
        self.seed = seed
        self.listening = listening
        self.port = 0
        self.started_s = 0.0
        self.connections = 0
        self._server: asyncio.Server | None = None
        self._log: TruthLog | None = None
        self._tasks: set[asyncio.Task[Any]] = set()

    @property
    def url(self) -> str:
        """The address pages use instead of the target's (``http://127.0.0.1:PORT``)."""
        return f"http://{LOOPBACK}:{self.port}"

    async def start(self) -> None:
        """Listen, and write the truth log's header and companion (the start is time 0)."""
        if self.listening is None:
            self._server = await asyncio.start_server(self._accept, LOOPBACK, 0)
        else:
            self._server = await asyncio.start_server(self._accept, sock=self.listening)
        self.port = self._server.sockets[0].getsockname()[1]
        self._log = TruthLog(self.log_path)
        wall_ns, monotonic_ns = time.time_ns(), time.monotonic_ns()
        self.started_s = monotonic_ns / 1e9
        write_companion(
            self.log_path,
            {
                "network": str(self.network),
                "seed": self.seed,
                "target": f"{self.target[0]}:{self.target[1]}",
                "proxy": self.url,
                "clock": "monotonic (time.monotonic_ns), s",
                "started_s": self.started_s,
                "anchor": {"monotonic_ns": monotonic_ns, "wall_ns": wall_ns},
            },
        )

    async def close(self) -> None:
        """Stop listening, end every connection and close the truth log."""
        if self._server is not None:
            self._server.close()
        for task in list(self._tasks):
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        if self._server is not None:
            await self._server.wait_closed()
        if self._log is not None:
            self._log.close()

    async def serve(self) -> None:
        """Carry connections (once started) until cancelled, then close."""
        try:
            await asyncio.Event().wait()
        finally:
            await self.close()

    async def _accept(self, page_r: asyncio.StreamReader, page_w: asyncio.StreamWriter) -> None:
        """Carry one page's connection to the target both ways until both streams end.

        A connection that fails (reset, refused by the target) is aborted both ways; so is
        every connection when the proxy closes (its handler cancelled).
        """
        task = asyncio.current_task()
        assert task is not None
        self._tasks.add(task)
        self.connections += 1
        number = self.connections
        writers = [page_w]
        try:
            server_r, server_w = await asyncio.open_connection(*self.target)
            writers.append(server_w)
            async with asyncio.TaskGroup() as lanes:
                lanes.create_task(self._carry(page_r, server_w, self._lane(number, "up")))
                lanes.create_task(self._carry(server_r, page_w, self._lane(number, "down")))
        except* (OSError, asyncio.CancelledError):
            for writer in writers:
                writer.transport.abort()
        finally:
            for writer in writers:
                writer.close()
            self._tasks.discard(task)

    def _lane(self, connection: int, direction: str) -> Lane:
        return Lane(connection, direction, lane_rng(self.seed, connection, direction))

    async def _carry(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, lane: Lane
    ) -> None:
        """Carry one direction: read and plan each chunk, deliver them in order."""
        delivering = asyncio.create_task(self._deliver(writer, lane))
        try:
            while data := await reader.read(CHUNK_BYTES):
                lane.queue.put_nowait((data, self._plan(lane, data)))
            lane.queue.put_nowait((b"", self._plan(lane, b"")))
            await delivering
        finally:
            delivering.cancel()

    def _plan(self, lane: Lane, data: bytes) -> Chunk:
        """Stamp a chunk received now, draw its delay and plan its delivery."""
        received = now_s()
        delay = self.network.delay(lane.direction).draw(lane.rng)
        due, cause = due_time(
            received - self.started_s, delay, lane.previous_s, self.network.stalls
        )
        lane.previous_s = due
        first = lane.count == 0 and lane.direction == "up"
        lane.count += 1
        return Chunk(
            lane.connection, lane.direction, lane.count - 1, len(data), received, delay,
            self.started_s + due, np.nan, cause, request_line(data) if first else "",
        )  # fmt: skip

    async def _deliver(self, writer: asyncio.StreamWriter, lane: Lane) -> None:
        """Write each chunk at its due time, then its row of the truth; half close at the end."""
        assert self._log is not None
        while True:
            data, chunk = await lane.queue.get()
            await asyncio.sleep(max(0.0, chunk.due_s - now_s()))
            delivered = now_s()
            if data:
                writer.write(data)
            elif writer.can_write_eof():
                writer.write_eof()
            self._log.write(_delivered(chunk, delivered))
            if not data:
                return
            await writer.drain()


def _delivered(chunk: Chunk, delivered_s: float) -> Chunk:
    return Chunk(**{**chunk.__dict__, "delivered_s": delivered_s})


class ProxyThread:
    """Run an `EmulatedInternet` on an event loop in a background thread (a context manager).

    Parameters
    ----------
    *args, **kwargs
        As `EmulatedInternet` takes them.

    Raises
    ------
    TimeoutError
        When the proxy does not listen within `START_TIMEOUT` (an `OSError` when it cannot).
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.proxy = EmulatedInternet(*args, **kwargs)
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True)

    @property
    def url(self) -> str:
        """The address pages use instead of the target's."""
        return self.proxy.url

    def __enter__(self) -> ProxyThread:
        self._thread.start()
        asyncio.run_coroutine_threadsafe(self.proxy.start(), self._loop).result(START_TIMEOUT)
        return self

    def __exit__(self, *exc: object) -> None:
        closing = asyncio.run_coroutine_threadsafe(self.proxy.close(), self._loop)
        with contextlib.suppress(TimeoutError):
            closing.result(START_TIMEOUT)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(START_TIMEOUT)
        self._loop.close()
