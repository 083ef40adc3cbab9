"""Test support, as ``numpy.testing`` is for numpy: what the tests and the benchmarks share.

Slow, obvious reference implementations the compiled code is checked and timed against
(`solve_step_bvp`, `python_learn_session`, `plug_in_transfer_entropy`), tasks with known answers
(`make_follower_sessions`, `swapped_roles`),
a real live server on a loopback port (`ServerThread`), and an avatar's player stepped in a
browser page and in Python on the same neighbours (`static_app`, `step_in_page`,
`step_in_python`, `partner_motion`). Nothing else in the package uses it.
"""

from __future__ import annotations

import base64
import json
import math
import os
import socket
import threading
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_bvp

from mirror_avatar.common.errors import InputError
from mirror_avatar.dynamics import CONTROL_PERIOD, HKBParams
from mirror_avatar.files.trials import Trial
from mirror_avatar.learning.agent import CyberPlayer
from mirror_avatar.learning.kernels import VELOCITY_WEIGHT
from mirror_avatar.players import Observation, Player, RecordedPlayer
from mirror_avatar.sessions.session import Session
from mirror_avatar.specs import bundled_generator
from mirror_avatar.training.avatar import Avatar, load_avatar
from mirror_avatar.training.imitation import make_cyber_player

if TYPE_CHECKING:
    from starlette.types import ASGIApp

    from mirror_avatar.realtime.settings import ConnectionSettings
    from mirror_avatar.realtime.tls import TlsFiles

Array = NDArray[np.float64]


def solve_step_bvp(
    params: HKBParams,
    x0: float,
    y0: float,
    rp: float,
    rs: float,
    rv: float,
    tol: float = 1e-8,
    n_nodes: int = 100,
) -> tuple[float, float, float]:
    """One optimal-control step by scipy's collocation solver on the nonlinear BVP of METHODS 5.

    With ``tol=1e-3`` and ``n_nodes=10`` this is what the original implementation's bvp4c did at
    every step; the default is a tight solution to check the compiled step against.

    Returns
    -------
    tuple of float
        Position and velocity at the end of the interval (not clipped) and the control at its
        start (units, units/s, units/s²).
    """
    a, b, g, w, eta = params.alpha, params.beta, params.gamma, params.omega, params.eta
    tp, tv, ts = params.theta_p, params.theta_v, params.theta_s

    def rhs(_t: Array, z: Array) -> Array:
        x, y, l1, l2 = z
        return np.vstack(
            [
                y,
                -(a * x * x + b * y * y - g) * y - w * w * x - l2 / eta,
                l2 * (2 * a * x * y + w * w),
                l2 * (a * x * x + 3 * b * y * y - g) - l1 - ts * (y - rs) - tv * (y - rv),
            ]
        )

    def boundary(za: Array, zb: Array) -> Array:
        return np.array([za[0] - x0, za[1] - y0, zb[2] - tp * (zb[0] - rp), zb[3]])

    t = np.linspace(0.0, params.period, n_nodes)
    guess = np.zeros((4, t.size))
    guess[0], guess[1] = x0 + y0 * t, y0
    solution = solve_bvp(rhs, boundary, t, guess, tol=tol, max_nodes=100_000)
    if not solution.success:
        raise RuntimeError(f"solve_bvp failed: {solution.message}")
    x_end, y_end = solution.sol(params.period)[:2]
    return float(x_end), float(y_end), float(-solution.sol(0.0)[3] / eta)


def python_learn_session(
    player: CyberPlayer,
    partner_x: Array,
    partner_v: Array,
    target_x: Array,
    target_v: Array,
    target_r: Array,
    learning_rate: float,
    discount: float,
    epsilon: float,
    draws: Array,
    random_actions: NDArray[np.int64],
) -> tuple[float, float]:
    """Q-learn one session in plain Python, as `mirror_avatar.learning.kernels.learn_session` does.

    Updates ``player.q_table_`` in place; returns the sum of rewards and the RMS to the target.
    """
    q, disc, actions = player.q_table_, player.discretisation_, list(player.actions_)
    p, n_substeps = player.params, int(player.n_substeps)
    h = p.period / n_substeps

    def acc(x: float, v: float, u: float) -> float:
        return -(p.alpha * x * x + p.beta * v * v - p.gamma) * v - p.omega**2 * x + u

    def cell(x: float, v: float, k: int) -> int:
        if disc.features == "reference":
            features = (x - partner_x[k], v - target_r[k], x, target_r[k])
        elif disc.features == "relative":
            features = (x - partner_x[k], v - partner_v[k], partner_x[k], partner_v[k])
        else:
            features = (x, v, partner_x[k], partner_v[k])
        index = 0
        for f, edges in zip(features, disc.edges, strict=True):
            index = index * (len(edges) + 1) + sum(1 for edge in edges if f >= edge)
        return index

    x, v = float(target_x[0]), float(target_v[0])
    total = squares = 0.0
    for k in range(len(partner_x) - 1):
        s = cell(x, v, k)
        a = int(random_actions[k]) if draws[k] < epsilon else int(np.argmax(q[s]))
        u = actions[a]
        for _ in range(n_substeps):
            a1 = acc(x, v, u)
            x2, v2 = x + h / 2 * v, v + h / 2 * a1
            a2 = acc(x2, v2, u)
            x3, v3 = x + h / 2 * v2, v + h / 2 * a2
            a3 = acc(x3, v3, u)
            x4, v4 = x + h * v3, v + h * a3
            a4 = acc(x4, v4, u)
            x, v = x + h / 6 * (v + 2 * v2 + 2 * v3 + v4), v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
        if abs(x) > 0.5:
            x, v = math.copysign(0.5, x), (min(v, 0.0) if x > 0 else max(v, 0.0))
        r = -((x - target_x[k + 1]) ** 2) - VELOCITY_WEIGHT * (v - target_v[k + 1]) ** 2
        r -= p.eta * u * u
        q[s, a] += learning_rate * (r + discount * max(q[cell(x, v, k + 1)]) - q[s, a])
        total += r
        squares += (x - target_x[k + 1]) ** 2
    return total, math.sqrt(squares / (len(partner_x) - 1))


def make_follower_sessions(
    trials: Iterable[Trial], lag: float = 0.3, period: float = CONTROL_PERIOD
) -> list[Session]:
    """Dyads from recorded trials with a known answer: a perfect follower with a fixed delay.

    Each trial, resampled to 1 / period, is player 0 (the partner); player 1 (the target) is
    the same motion ``lag`` seconds later (rounded to whole periods, at least one). Trials are
    cut to the shortest one.
    """
    shift = max(round(lag / period), 1)
    pairs = []
    for trial in trials:
        uniform = trial.resampled(1.0 / period)
        x, v = uniform.positions, uniform.velocity()
        pairs.append((np.stack([x[shift:], x[:-shift]]), np.stack([v[shift:], v[:-shift]])))
    if not pairs:
        raise InputError("trials", "no trials to build sessions from")
    n = min(x.shape[1] for x, _ in pairs)
    times = np.arange(n) * period
    return [
        Session(times, x[:, :n], v[:, :n], np.full((2, n), np.nan), np.full((2, n), np.nan))
        for x, v in pairs
    ]


class ServerThread:
    """Run an ASGI app on a free loopback port in a background thread (a context manager).

    Used by the tests and the benchmark to talk to a real server over real sockets.

    Parameters
    ----------
    app
        The application to serve.
    host
        Address to bind (port chosen by the operating system).
    stop_timeout
        Seconds the server is given to stop gracefully when the block ends; then it is stopped
        without waiting for its connections, and given as long again.
    guard
        Its request deadlines and connection caps (default: the servers' own).
    tls
        Its certificate and key: it serves HTTPS and secure WebSockets (default: plain HTTP).
    port
        The port to bind (0: one the operating system chooses).

    Raises
    ------
    RuntimeError
        When the server did not start within 10 s, or did not stop (on leaving the block).
    """

    def __init__(
        self,
        app: ASGIApp,
        host: str = "127.0.0.1",
        stop_timeout: float = 15.0,
        guard: ConnectionSettings | None = None,
        tls: TlsFiles | None = None,
        port: int = 0,
    ) -> None:
        # Imported here so that the rest of this module works without the live extra.
        from mirror_avatar.realtime.transport import listening_socket, make_server

        self.socket = listening_socket(host, port)
        self.host, self.port = self.socket.getsockname()[:2]
        self.scheme = "http" if tls is None else "https"
        self.server = make_server(app, self.host, self.port, guard=guard, tls=tls)
        self.stop_timeout = stop_timeout
        self.thread = threading.Thread(
            target=self.server.run, kwargs={"sockets": [self.socket]}, daemon=True
        )

    @property
    def url(self) -> str:
        """The server's base URL (``http://`` or, with a certificate, ``https://``)."""
        return f"{self.scheme}://{self.host}:{self.port}"

    def __enter__(self) -> ServerThread:
        self.thread.start()
        deadline = time.monotonic() + 10.0
        while not self.server.started:
            if time.monotonic() > deadline or not self.thread.is_alive():
                raise RuntimeError("the live server did not start")
            time.sleep(0.01)
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.should_exit = True
        self.thread.join(self.stop_timeout)
        if self.thread.is_alive():  # a connection's handler ignored the shutdown
            self.server.force_exit = True
            self.thread.join(self.stop_timeout)
        self.socket.close()
        if self.thread.is_alive() and exc[0] is None:
            raise RuntimeError(f"the live server did not stop in {2 * self.stop_timeout:g} s")


def raw_websocket(
    port: int, source: str = "127.0.0.1", receive_buffer: int | None = None, path: str = "/ws"
) -> socket.socket:
    """Open a WebSocket to ``path`` of a loopback server by hand, as a hostile client would.

    The handshake is sent from ``source`` (any loopback address) and the server's answer is
    left unread. ``receive_buffer`` (bytes) sets a small receive window before connecting: a
    client that stops reading then fills it quickly.
    """
    sock = socket.socket()
    if receive_buffer is not None:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
    sock.bind((source, 0))
    sock.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
        f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
        "Sec-WebSocket-Version: 13\r\n\r\n".encode()
    )
    return sock


def text_frame(text: str) -> bytes:
    """Make a masked (with a zero key) WebSocket text frame of fewer than 126 bytes."""
    data = text.encode()
    return bytes([0x81, 0x80 | len(data)]) + bytes(4) + data


def smooth_motion(rng: np.random.Generator, n: int, rate: float, cutoff: float = 1.0) -> Array:
    """Band-limited random motion: white noise low-passed at ``cutoff`` (Hz), shape (n,)."""
    from scipy import signal

    sos = signal.butter(4, cutoff, fs=rate, output="sos")
    return np.asarray(signal.sosfiltfilt(sos, rng.normal(size=n + 2000))[1000 : 1000 + n])


def swapped_roles(rng: np.random.Generator, n: int, delay: int, rate: float) -> tuple[Array, Array]:
    """Two positions whose leader swaps halfway: known leadership for its measures.

    Player 1 repeats player 0's `smooth_motion` ``delay`` samples later for the first ``n // 2``
    samples, then player 0 repeats player 1's; shape (n,) each.
    """
    s = smooth_motion(rng, n + delay, rate)
    t = np.arange(n)
    first = t < n // 2
    return np.where(first, s[t + delay], s[t]), np.where(first, s[t], s[t + delay])


def plug_in_transfer_entropy(source: ArrayLike, target: ArrayLike, k: int) -> float:
    """Schreiber's transfer entropy (bits) of discrete series by counting states, slowly.

    Rows of 2-D inputs are independent series of one process, pooled (as pyinform pools them).
    """
    from collections import Counter

    joint: Counter[tuple[Any, ...]] = Counter()
    past_source: Counter[tuple[Any, ...]] = Counter()
    past: Counter[tuple[Any, ...]] = Counter()
    past_next: Counter[tuple[Any, ...]] = Counter()
    total = 0
    rows = zip(np.atleast_2d(source).tolist(), np.atleast_2d(target).tolist(), strict=True)
    for x, y in rows:
        for t in range(k - 1, len(y) - 1):
            history = tuple(y[t - k + 1 : t + 1])
            joint[(y[t + 1], history, x[t])] += 1
            past_source[(history, x[t])] += 1
            past[history] += 1
            past_next[(y[t + 1], history)] += 1
            total += 1
    te = 0.0
    for (following, history, x_t), count in joint.items():
        conditional = count / past_source[(history, x_t)]
        marginal = past_next[(following, history)] / past[history]
        te += count / total * math.log2(conditional / marginal)
    return te


def partner_motion(trials: Sequence[Trial], n_steps: int) -> tuple[Array, Array]:
    """Return the motion of recorded neighbours on the control grid, one per trial.

    Each trial replayed as `mirror_avatar.players.RecordedPlayer` replays it (still at its last
    position once it ends).

    Returns
    -------
    tuple of numpy.ndarray
        Positions (units) and velocities (units/s) at samples 0..n_steps, shape
        (n_steps + 1, len(trials)).
    """
    states = np.empty((n_steps + 1, len(trials), 2))
    for j, trial in enumerate(trials):
        player = RecordedPlayer(trial)
        states[0, j] = player.reset()
        for k in range(n_steps):
            states[k + 1, j] = player.step(Observation(k, *[np.empty(0)] * 3))
    return states[..., 0].copy(), states[..., 1].copy()


def seeded_avatar(agent: str, folder: Path) -> Avatar:
    """Return a personal avatar of untrained, seeded ``agent`` policies, saved and read back.

    Its file is ``folder / f"{agent}.npz"`` (a player spec for the lab).
    """
    generator = bundled_generator("slow")
    players = {}
    for seed, role in enumerate(("follower", "leader")):
        players[role] = make_cyber_player(role, generator, agent=agent)  # type: ignore[arg-type]
        players[role].initialise_policy(seed)
        players[role].training_ = {"role": role}
    path = Avatar("P01", generator, players).save(folder / f"{agent}.npz")
    return load_avatar(path)


def step_in_python(player: Player, seed: int, positions: Array, velocities: Array) -> Array:
    """Positions of ``player`` reset with ``seed`` and stepped against neighbours' motion.

    Parameters
    ----------
    positions, velocities
        The neighbours' states at samples 0..n (units, units/s), shape (n + 1, m).

    Returns
    -------
    numpy.ndarray
        The player's position and velocity at samples 0..n, shape (n + 1, 2).
    """
    states = [player.reset(seed)]
    for k in range(positions.shape[0] - 1):
        previous = positions[max(k - 1, 0)]
        states.append(player.step(Observation(k, positions[k], velocities[k], previous)))
    return np.asarray(states, dtype=np.float64)


STEP_IN_PAGE = """async ({text, positions, velocities, block}) => {
  const { makePlayer } = await import("/static/avatars.js");
  const began = performance.now();
  const player = makePlayer(JSON.parse(text));
  const load = performance.now() - began;
  const states = [player.reset()];
  const blocks = [];
  for (let first = 0; first < positions.length - 1; first += block) {
    const start = performance.now();
    const stop = Math.min(first + block, positions.length - 1);
    for (let k = first; k < stop; k++) {
      states.push(player.step({ positions: positions[k], velocities: velocities[k] }));
    }
    blocks.push((performance.now() - start) / (stop - first));
  }
  return { states, load, blocks };
}"""
"""Build a player in the page from its message's text and step it (`step_in_page`)."""


def step_in_page(
    page: Any, message: dict[str, Any], positions: Array, velocities: Array, block: int = 1
) -> tuple[Array, float, Array]:
    """Build a player in a browser page from its message (`mirror_avatar.browser`) and step it.

    The page must be at a server mounting the lab's static folder at ``/static`` (`static_app`).

    Parameters
    ----------
    page
        A Playwright page.
    message
        What `mirror_avatar.browser.browser_arrays` returned, sent as its JSON text.
    positions, velocities
        The neighbours' states, as `step_in_python` takes them.
    block
        Steps timed together (the page's clock is coarse).

    Returns
    -------
    tuple
        The player's states at samples 0..n, shape (n + 1, 2); the time to parse the message
        and build the player (ms); each block's time per step (ms).
    """
    answer = page.evaluate(
        STEP_IN_PAGE,
        {
            "text": json.dumps(message),
            "positions": positions.tolist(),
            "velocities": velocities.tolist(),
            "block": block,
        },
    )
    return (
        np.asarray(answer["states"], dtype=np.float64),
        answer["load"],
        np.asarray(answer["blocks"]),
    )


BLANK_PAGE = "<!doctype html><title>players</title>"


def static_app() -> ASGIApp:
    """Return an app serving a blank page at ``/`` and the lab's static folder at ``/static``.

    The page is cross-origin isolated (COOP and COEP headers), so its clock
    (``performance.now``) ticks in 5 µs rather than 100 µs.
    """
    from starlette.applications import Starlette
    from starlette.responses import HTMLResponse
    from starlette.routing import Mount, Route
    from starlette.staticfiles import StaticFiles

    from mirror_avatar.lab.running.server import STATIC

    isolated = {"Cross-Origin-Opener-Policy": "same-origin",
                "Cross-Origin-Embedder-Policy": "require-corp"}  # fmt: skip

    async def blank(request: object) -> HTMLResponse:
        return HTMLResponse(BLANK_PAGE, headers=isolated)

    return Starlette(
        routes=[Route("/", blank), Mount("/static", StaticFiles(directory=STATIC), name="static")]
    )
