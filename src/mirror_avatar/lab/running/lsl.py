"""Lab Streaming Layer (LSL): the session's position outlet and LSL streams as input devices.

`SessionOutlet` publishes every player's position of a lab trial as one LSL stream (type
``"Position"``, one float64 channel per player, in playing range units), so a recorder such as
LabRecorder stores it next to EEG or motion capture on the same clock, and the session's events
(a trial's first and last sample, a participant's drop, an avatar's perturbation, a study's
condition) as a second stream of string markers (type ``"Markers"``, named as the positions
with `` markers`` appended), for epoching. A study session's outlet has one channel per player
label of the participant's whole run, NaN while that player is not in the condition
(`mirror_avatar.lab.running.study.ParticipantRun.channels`).
`LslInput` reads one channel of another LSL stream (a hand tracker, a slider) as a person's input
device: a background thread keeps the newest sample, mapped to the playing range, for the
session's clock to read.

Time stamps are LSL time (`pylsl.local_clock`, s). pylsl is an optional dependency (the ``lsl``
extra); it is imported when an outlet or an input is made.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mirror_avatar.common.errors import InputError
from mirror_avatar.engine.loop import row_positions
from mirror_avatar.files.trials import PLAYING_RANGE
from mirror_avatar.realtime.inputs import Sample

STREAM_TYPE = "Position"
"""LSL content type of the session's outlet."""

MARKER_TYPE = "Markers"
"""LSL content type of the session's event stream."""

UNIT = "playing range units (-0.5..0.5)"
"""Unit of the outlet's channels, as written in its metadata."""

KINDS = ("human", "avatar")
"""Kinds of player a channel of the outlet can belong to."""

PULL_TIMEOUT = 0.05
"""Longest wait of the input thread for a sample (s); also bounds how long `close` takes."""

_MISSING = "pylsl is not installed: pip install 'mirror-avatar[lsl]'"


def _import_pylsl(source: str) -> Any:
    """Return the pylsl module, or raise InputError naming ``source`` when it is missing."""
    try:
        import pylsl
    except ImportError:
        raise InputError(source, _MISSING) from None
    return pylsl


def _where(stream: str) -> str:
    return f"LSL stream {stream!r}"


class SessionOutlet:
    """A lab trial's positions published as an LSL outlet.

    The stream has type ``"Position"``, one float64 channel per player (position in playing
    range units, -0.5..0.5) and nominal rate ``1 / period`` (Hz). Its description holds
    ``<channels>`` (per player: ``label``, ``role``, ``kind``, ``unit``, ``type``),
    ``<acquisition>`` (``manufacturer``, ``model``) and ``<session>`` (``period_s``).

    Parameters
    ----------
    name
        The stream's name, as recorders list it.
    source_id
        A name unique to this session, so a recorder can reconnect to it after a network break.
    labels
        The players' names, one per channel.
    roles
        The players' roles (for instance ``"leader"``), one per channel.
    kinds
        ``"human"`` or ``"avatar"``, one per channel (a study's channel that is one or the
        other from one condition to the next: ``"human/avatar"``).
    period
        Control period T (s); the nominal rate is ``1 / period`` (Hz).

    Raises
    ------
    InputError
        If pylsl is missing, the three lists differ in length or are empty, a kind is unknown or
        the period is not positive.
    """

    def __init__(
        self,
        name: str,
        source_id: str,
        labels: Sequence[str],
        roles: Sequence[str],
        kinds: Sequence[str],
        period: float,
    ) -> None:
        _check_players(name, labels, roles, kinds, period)
        pylsl = _import_pylsl(_where(name))
        info = pylsl.StreamInfo(
            name, STREAM_TYPE, len(labels), 1.0 / period, pylsl.cf_double64, source_id
        )
        _describe(info.desc(), labels, roles, kinds, period)
        markers = pylsl.StreamInfo(
            f"{name} markers", MARKER_TYPE, 1, pylsl.IRREGULAR_RATE, pylsl.cf_string,
            f"{source_id}-markers",
        )  # fmt: skip
        self.name = name
        self.n_players = len(labels)
        self._clock = pylsl.local_clock
        self._outlet: Any = pylsl.StreamOutlet(info)
        self._markers: Any = pylsl.StreamOutlet(markers)

    def push(self, row: NDArray[np.float64]) -> None:
        """Publish one engine row, time-stamped with the LSL clock now.

        Parameters
        ----------
        row
            Shape (1 + 4N,): time (s), then per player position (units), velocity (units/s),
            control and reference; the positions (`mirror_avatar.engine.loop.row_positions`) are
            published.
        """
        row = np.asarray(row, dtype=np.float64)
        if row.shape != (1 + 4 * self.n_players,):
            raise ValueError(
                f"an engine row of {self.n_players} players has shape "
                f"({1 + 4 * self.n_players},), got {row.shape}"
            )
        self.push_positions(row_positions(row))

    def push_positions(self, positions: ArrayLike, timestamp: float | None = None) -> None:
        """Publish the players' positions.

        Parameters
        ----------
        positions
            Shape (N,), one position per player (units).
        timestamp
            LSL time of the sample (s, `pylsl.local_clock`); None stamps it with the clock now.
        """
        values = np.asarray(positions, dtype=np.float64)
        if values.shape != (self.n_players,):
            raise ValueError(f"expected {self.n_players} positions, got shape {values.shape}")
        stamp = self._clock() if timestamp is None else float(timestamp)
        self._open().push_sample(values.tolist(), stamp)

    def mark(self, event: str, timestamp: float | None = None) -> None:
        """Publish an event on the marker stream.

        Parameters
        ----------
        event
            What happened, for instance ``"trial 1 start"``.
        timestamp
            LSL time of the event (s); None stamps it with the clock now.
        """
        stamp = self._clock() if timestamp is None else float(timestamp)
        self._open()
        self._markers.push_sample([event], stamp)

    def wait_for_consumers(self, timeout: float) -> bool:
        """Wait up to ``timeout`` (s) for a consumer (a recorder's inlet); return whether one is."""
        return bool(self._open().wait_for_consumers(timeout))

    def close(self) -> None:
        """Withdraw the stream: it can no longer be resolved and its inlets stop receiving.

        pylsl's outlet has no close method: dropping the last reference destroys it.
        """
        self._outlet = None
        self._markers = None

    def __enter__(self) -> SessionOutlet:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _open(self) -> Any:
        if self._outlet is None:
            raise RuntimeError(f"the LSL outlet {self.name!r} is closed")
        return self._outlet


def _check_players(
    name: str, labels: Sequence[str], roles: Sequence[str], kinds: Sequence[str], period: float
) -> None:
    where = _where(name)
    if not labels or not len(labels) == len(roles) == len(kinds):
        raise InputError(where, "needs as many labels, roles and kinds, at least one of each")
    unknown = sorted({part for kind in kinds for part in kind.split("/")} - set(KINDS))
    if unknown:
        raise InputError(where, f"unknown player kind {unknown[0]!r} (use human or avatar)")
    if not (math.isfinite(period) and period > 0.0):
        raise InputError(where, f"the period must be positive (s), got {period}")


def _describe(
    desc: Any, labels: Sequence[str], roles: Sequence[str], kinds: Sequence[str], period: float
) -> None:
    """Write the channels, acquisition and session metadata into a stream's description."""
    channels = desc.append_child("channels")
    for label, role, kind in zip(labels, roles, kinds, strict=True):
        channel = channels.append_child("channel")
        channel.append_child_value("label", str(label))
        channel.append_child_value("role", str(role))
        channel.append_child_value("kind", str(kind))
        channel.append_child_value("unit", UNIT)
        channel.append_child_value("type", STREAM_TYPE)
    acquisition = desc.append_child("acquisition")
    acquisition.append_child_value("manufacturer", "mirror-avatar")
    acquisition.append_child_value("model", "mirror game")
    desc.append_child("session").append_child_value("period_s", repr(float(period)))


class LslInput:
    """One channel of an LSL stream as a person's input device (an `InputSource`).

    A daemon thread pulls the stream continuously. Each value v becomes the position
    ``x = offset + scale * v`` (units), clipped to the playing range; `latest` returns the newest.
    Values that are NaN or infinite (tracking lost) are counted in `invalid` and otherwise ignored,
    so the person's position is held rather than invented.
    For a hand tracker in millimetres where 600 mm span the playing range (1 unit), use
    ``scale = 1/600`` and ``offset = -centre / 600`` with ``centre`` the middle of the range (mm).

    Parameters
    ----------
    stream
        The stream's name (its ``name`` property in LSL).
    channel
        The channel holding the position (0-based).
    scale
        Units per stream unit (for millimetres with 600 mm = 1 unit: 1/600).
    offset
        Position (units) of the stream value 0.
    timeout
        Longest wait (s) to find the stream, open it and get its first clock offset.
    source_id
        The stream's source id, when several streams share its name (None: the name must be
        unique on the network).

    Attributes
    ----------
    stream, channel, scale, offset
        As given.

    Raises
    ------
    InputError
        If pylsl is missing, no stream of that name is found within ``timeout``, several are
        and no ``source_id`` says which (the error lists them), ``channel`` is not one of its
        channels, its channels are not numbers, or it cannot be opened.

    Notes
    -----
    Thread-safe: the pulling thread and readers share a lock. `last_timestamp` is in the local LSL
    clock: the sender's time stamp plus the inlet's `time_correction` (which, between two
    programs on one computer, is a small estimation error of some microseconds, not zero).
    When a stream that has a source id goes away, liblsl waits for it to come back: `latest`
    keeps the last sample meanwhile (a `HumanPlayer` counts those ticks as held). A stream
    without one is lost for good, and `error` says so.
    """

    def __init__(
        self,
        stream: str,
        channel: int = 0,
        scale: float = 1.0,
        offset: float = 0.0,
        timeout: float = 5.0,
        source_id: str | None = None,
    ) -> None:
        _check_mapping(stream, scale, offset, timeout)
        pylsl = _import_pylsl(_where(stream))
        self.stream, self.channel, self.scale, self.offset = stream, channel, scale, offset
        info = _resolve(pylsl, stream, channel, timeout, source_id)
        self._inlet: Any = pylsl.StreamInlet(info, max_buflen=10)
        self._info, correction = _open_inlet(self._inlet, stream, timeout)
        self._lock = threading.Lock()
        self._latest: Sample | None = None
        self._correction = correction
        self._timestamp = math.nan
        self._n_received = 0
        self._clipped = 0
        self._invalid = 0
        self._error: str | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"lsl {stream}", daemon=True)
        self._thread.start()

    def latest(self) -> Sample | None:
        """Return the newest sample: position (units), ``seq`` (1, 2, ...) and arrival time.

        Returns
        -------
        Sample or None
            ``received`` is `time.monotonic` (s) when the sample's chunk arrived; None before the
            first sample.
        """
        with self._lock:
            return self._latest

    @property
    def n_received(self) -> int:
        """Number of samples received (including invalid ones)."""
        with self._lock:
            return self._n_received

    @property
    def clipped(self) -> int:
        """Number of samples whose mapped position left the playing range (and were clipped)."""
        with self._lock:
            return self._clipped

    @property
    def invalid(self) -> int:
        """Number of samples ignored because their value was NaN or infinite (tracking lost)."""
        with self._lock:
            return self._invalid

    @property
    def last_timestamp(self) -> float:
        """LSL time stamp of the `latest` sample in the local LSL clock (s); NaN before any."""
        with self._lock:
            return self._timestamp

    @property
    def time_correction(self) -> float:
        """Clock offset (s) that was added to the sender's time stamp to give `last_timestamp`."""
        with self._lock:
            return self._correction

    @property
    def error(self) -> str | None:
        """Why the thread stopped pulling (the stream was lost), or None while it runs."""
        with self._lock:
            return self._error

    def describe(self) -> dict[str, Any]:
        """Return the device for a session's metadata (JSON-serialisable).

        Returns
        -------
        dict
            ``stream``, ``type``, ``source_id``, ``hostname``, ``channel``, ``channel_count``,
            ``nominal_rate`` (Hz, 0 for an irregular stream), ``scale`` (units per stream unit),
            ``offset`` (units), and the samples ``received``, ``invalid`` and ``clipped`` so far.
        """
        with self._lock:
            counts = {
                "received": self._n_received,
                "invalid": self._invalid,
                "clipped": self._clipped,
            }
        return counts | {
            "stream": self.stream,
            "type": self._info.type(),
            "source_id": self._info.source_id(),
            "hostname": self._info.hostname(),
            "channel": self.channel,
            "channel_count": self._info.channel_count(),
            "nominal_rate": self._info.nominal_srate(),
            "scale": self.scale,
            "offset": self.offset,
        }

    def close(self) -> None:
        """Stop the thread and close the inlet (the last sample stays readable)."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(10 * PULL_TIMEOUT + 1.0)
        if self._inlet is not None and not self._thread.is_alive():
            self._inlet.close_stream()
            self._inlet = None

    def __enter__(self) -> LslInput:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                values, stamps = self._pull()
            except RuntimeError as error:
                with self._lock:
                    self._error = f"{_where(self.stream)}: {error or type(error).__name__}"
                return
            if stamps:
                self._store(values, np.asarray(stamps), self._current_correction())

    def _pull(self) -> tuple[NDArray[np.float64], list[float]]:
        """Wait for one sample, then take every sample already there (the channel's values)."""
        first, stamp = self._inlet.pull_sample(timeout=PULL_TIMEOUT)
        if first is None:
            return np.empty(0), []
        rest, stamps = self._inlet.pull_chunk(timeout=0.0)
        samples = np.asarray([first, *rest], dtype=np.float64)
        return samples[:, self.channel], [stamp, *stamps]

    def _current_correction(self) -> float:
        """Return the inlet's clock offset (s), or the previous one while it is re-estimated."""
        try:
            return float(self._inlet.time_correction(0.0))
        except RuntimeError:
            return self.time_correction

    def _store(
        self, values: NDArray[np.float64], stamps: NDArray[np.float64], correction: float
    ) -> None:
        """Keep the newest valid sample of a chunk: values (stream units), stamps (sender's s)."""
        received = time.monotonic()
        low, high = PLAYING_RANGE
        x = self.offset + self.scale * values
        valid = np.isfinite(x)
        x, stamps = x[valid], stamps[valid]
        with self._lock:
            self._n_received += len(values)
            self._invalid += len(values) - len(x)
            if not len(x):
                return
            self._clipped += int(np.count_nonzero((x < low) | (x > high)))
            seq = (0 if self._latest is None else self._latest.seq) + len(x)
            self._latest = Sample(float(np.clip(x[-1], low, high)), seq, received)
            self._timestamp = float(stamps[-1]) + correction
            self._correction = correction


def _check_mapping(stream: str, scale: float, offset: float, timeout: float) -> None:
    where = _where(stream)
    if not (math.isfinite(scale) and scale != 0.0):
        raise InputError(where, f"scale must be a finite non-zero number, got {scale}")
    if not math.isfinite(offset):
        raise InputError(where, f"offset must be finite, got {offset}")
    if not (math.isfinite(timeout) and timeout > 0.0):
        raise InputError(where, f"timeout must be positive (s), got {timeout}")


RESOLVE_WAIT = 0.5
"""Seconds the resolution keeps listening after the first stream of the name answers, so that
a second stream of the same name is seen too."""


def _resolve(
    pylsl: Any, stream: str, channel: int, timeout: float, source_id: str | None = None
) -> Any:
    """Find the stream by name (and source id) and check that ``channel`` is a numeric one.

    Several streams of the name without a ``source_id`` choosing one are refused, naming each
    stream's source id and host.
    """
    where = _where(stream)
    found = pylsl.resolve_byprop("name", stream, timeout=timeout)
    if not found:
        raise InputError(where, f"no stream of that name found on the network within {timeout} s")
    found = (
        pylsl.resolve_byprop("name", stream, minimum=len(found) + 1, timeout=RESOLVE_WAIT) or found
    )
    if source_id is not None:
        found = [info for info in found if info.source_id() == source_id]
        if not found:
            raise InputError(where, f"no stream of that name has source id {source_id!r}")
    if len(found) > 1:
        listed = "; ".join(f"source id {i.source_id()!r} on {i.hostname()}" for i in found)
        raise InputError(
            where,
            f"{len(found)} streams have this name ({listed}): give the plan's lsl.source_id",
        )
    info = found[0]
    count = info.channel_count()
    if not 0 <= channel < count:
        raise InputError(where, f"has {count} channel(s) (0..{count - 1}), not channel {channel}")
    if info.channel_format() in (pylsl.cf_string, pylsl.cf_undefined):
        raise InputError(where, "its channels are not numbers")
    return info


def _open_inlet(inlet: Any, stream: str, timeout: float) -> tuple[Any, float]:
    """Fetch the stream's full description, subscribe to its data and get the clock offset.

    Returns the description and the offset (s) to add to the sender's time stamps. Fetching the
    description first matters: liblsl's first ``pull_chunk`` otherwise fetches it with no time
    limit, and hangs for good if the sender has gone.
    """
    try:
        info = inlet.info(timeout)
        inlet.open_stream(timeout)
        correction = float(inlet.time_correction(timeout))
    except RuntimeError as error:
        raise InputError(_where(stream), f"cannot be opened ({error or 'timed out'})") from None
    return info, correction
