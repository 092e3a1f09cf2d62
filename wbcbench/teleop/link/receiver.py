"""Live pose stream: a non-blocking UDP receiver of :mod:`wbcbench.teleop.link.protocol` datagrams.

Call :meth:`UdpPoseReceiver.poll` once per control tick: it drains the socket without blocking, keeps the newest
frame, and counts what it drops. Nothing a sender does (or fails to do) raises: datagrams that are lost,
reordered, duplicated or malformed are counted in :attr:`UdpPoseReceiver.stats`.

Sequence rules (``seq`` is uint32 and wraps; "newer" is serial-number arithmetic, RFC 1982):

* newer than the latest frame: accepted; the skipped numbers are counted as ``lost`` (and remembered for
  ``window`` frames);
* equal to the latest, or already seen within the last ``window`` frames: ``duplicates``;
* older, and one of the missing numbers: ``reordered`` (``lost`` decreases by one); the frame is dropped, since a
  newer one is already held;
* older and not seen within the window: ``reordered`` when within ``window`` of the latest, else the sender is
  taken to have restarted: the datagram is accepted and ``restarts`` counts it. A forward jump of more than
  ``window`` is also a restart (no flood of ``lost``).

Liveness: the status is ``waiting`` before the first accepted frame, ``stale`` when no frame has been accepted for
``stale_after`` seconds (receiver clock, default 0.2 s), else ``live``. Duplicates, late and malformed datagrams
do not refresh liveness.
"""

from __future__ import annotations

import enum
import socket
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from ...errors import ConfigError
from .protocol import DatagramError, decode_datagram
from ..io.recording import PoseFrame
from ..io.segments import MVN_SEGMENT_IDS

__all__ = ["StreamStatus", "ReceiverStats", "ReceivedFrame", "UdpPoseReceiver"]

_MASK = 0xFFFFFFFF
_HALF = 1 << 31


class StreamStatus(str, enum.Enum):
    """State of a live stream."""

    WAITING = "waiting"
    LIVE = "live"
    STALE = "stale"


@dataclass(frozen=True)
class ReceiverStats:
    """Counters since the receiver was opened (datagrams unless noted).

    Attributes:
        received: datagrams read from the socket.
        accepted: frames that became the latest.
        duplicates: repeated sequence numbers.
        reordered: late datagrams (older than the latest frame), dropped.
        lost: sequence numbers skipped and not (yet) received.
        malformed: datagrams that failed to decode (see :mod:`wbcbench.teleop.link.protocol`).
        restarts: sequence discontinuities taken as a sender restart.
        unknown_segments: segment entries with an id the receiver does not map (ignored).
        last_error: reason of the last malformed datagram ("" if none).
    """

    received: int = 0
    accepted: int = 0
    duplicates: int = 0
    reordered: int = 0
    lost: int = 0
    malformed: int = 0
    restarts: int = 0
    unknown_segments: int = 0
    last_error: str = ""


class ReceivedFrame(NamedTuple):
    """The latest accepted frame.

    Attributes:
        sequence: its sequence number.
        timestamp: the sender's timestamp [s].
        arrival: receiver clock at reception [s].
        positions: segment name -> position (3,) [m].
        orientations: segment name -> quaternion (4,) x y z w.
    """

    sequence: int
    timestamp: float
    arrival: float
    positions: Mapping[str, np.ndarray]
    orientations: Mapping[str, np.ndarray]


class UdpPoseReceiver:
    """Receive the pose stream on a UDP port, without blocking.

    Args:
        port: UDP port; 0 picks a free one (read it back from :attr:`port`); None: no socket, datagrams come
            only through :meth:`feed` (the simulated link of :mod:`wbcbench.teleop.link.network`).
        host: address to bind, default loopback ``127.0.0.1``.
        stale_after: seconds without an accepted frame before the status is ``stale`` (> 0).
        segment_ids: segment name -> id map of the stream (default: the 23 MVN segments).
        clock: time source [s] for arrivals and staleness (default ``time.monotonic``).
        window: how many past sequence numbers are remembered (duplicates, late arrivals).
        max_per_poll: upper bound on datagrams read by one :meth:`poll`.

    Raises:
        ConfigError: invalid argument or the address cannot be bound.
    """

    def __init__(
        self,
        port: int | None = 0,
        host: str = "127.0.0.1",
        *,
        stale_after: float = 0.2,
        segment_ids: Mapping[str, int] = MVN_SEGMENT_IDS,
        clock: Callable[[], float] = time.monotonic,
        window: int = 1024,
        max_per_poll: int = 4096,
    ) -> None:
        if not (stale_after > 0.0):
            raise ConfigError(f"stale_after must be > 0 s, got {stale_after!r}", key="stale_after")
        if window < 1 or max_per_poll < 1:
            raise ConfigError("window and max_per_poll must be >= 1", key="window")
        self._names = {int(i): str(name) for name, i in segment_ids.items()}
        if len(self._names) != len(segment_ids):
            raise ConfigError("segment ids must be unique", key="segment_ids")
        self._stale_after = float(stale_after)
        self._clock = clock
        self._window = int(window)
        self._max_per_poll = int(max_per_poll)
        self._sock = None
        if port is not None:
            self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                self._sock.bind((host, int(port)))
            except (OSError, OverflowError) as exc:
                self._sock.close()
                raise ConfigError(f"cannot bind UDP {host}:{port} ({getattr(exc, 'strerror', None) or exc})",
                                  key="port") from None
            self._sock.setblocking(False)
        self._stats = ReceiverStats()
        self._latest: ReceivedFrame | None = None
        self._seen: deque[int] = deque()
        self._seen_set: set[int] = set()
        self._missing: set[int] = set()

    # ------------------------------------------------------------------------------------------ socket
    @property
    def port(self) -> int:
        """The bound UDP port (0 without a socket)."""
        return int(self._sock.getsockname()[1]) if self._sock is not None else 0

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port) (("", 0) without a socket)."""
        if self._sock is None:
            return "", 0
        host, port = self._sock.getsockname()[:2]
        return str(host), int(port)

    def close(self) -> None:
        """Close the socket (idempotent)."""
        if self._sock is not None:
            self._sock.close()

    def __enter__(self) -> "UdpPoseReceiver":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------------------------------ polling
    def poll(self) -> int:
        """Read every datagram waiting on the socket (at most ``max_per_poll``) without blocking.

        Returns:
            The number of frames accepted by this call.
        """
        accepted = 0
        if self._sock is None:
            return 0
        for _ in range(self._max_per_poll):
            try:
                data = self._sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # e.g. ICMP errors surfaced on some platforms, or a closed socket
                break
            accepted += self.feed(data)
        return accepted

    def feed(self, data: bytes, arrival: float | None = None) -> int:
        """Process one datagram as if it had just been received (used by :meth:`poll`; handy in tests).

        Returns:
            1 if the datagram became the latest frame, else 0.
        """
        now = self._clock() if arrival is None else float(arrival)
        st = self._stats
        st = replace(st, received=st.received + 1)
        try:
            dgram = decode_datagram(data)
        except DatagramError as exc:
            self._stats = replace(st, malformed=st.malformed + 1, last_error=str(exc))
            return 0
        seq = dgram.sequence
        accept = False
        if self._latest is None:
            accept = True
        else:
            latest = self._latest.sequence
            ahead = (seq - latest) & _MASK
            if ahead == 0:
                st = replace(st, duplicates=st.duplicates + 1)
            elif ahead < _HALF:
                if ahead - 1 > self._window:
                    st = replace(st, restarts=st.restarts + 1)
                    self._reset_history()
                else:
                    for k in range(1, ahead):
                        self._missing.add((latest + k) & _MASK)
                    st = replace(st, lost=st.lost + ahead - 1)
                accept = True
            else:
                behind = (latest - seq) & _MASK
                if seq in self._missing:
                    self._missing.discard(seq)
                    st = replace(st, lost=st.lost - 1, reordered=st.reordered + 1)
                elif seq in self._seen_set:
                    st = replace(st, duplicates=st.duplicates + 1)
                elif behind <= self._window:
                    st = replace(st, reordered=st.reordered + 1)
                else:
                    st = replace(st, restarts=st.restarts + 1)
                    self._reset_history()
                    accept = True
        self._remember(seq)
        if accept:
            positions: dict[str, np.ndarray] = {}
            orientations: dict[str, np.ndarray] = {}
            unknown = 0
            for seg_id, (p, q) in dgram.poses.items():
                name = self._names.get(seg_id)
                if name is None:
                    unknown += 1
                    continue
                positions[name], orientations[name] = p, q
            self._latest = ReceivedFrame(seq, dgram.timestamp, now, positions, orientations)
            st = replace(st, accepted=st.accepted + 1, unknown_segments=st.unknown_segments + unknown)
            self._prune(seq)
        self._stats = st
        return int(accept)

    def _remember(self, seq: int) -> None:
        if seq in self._seen_set:
            return
        self._seen.append(seq)
        self._seen_set.add(seq)
        while len(self._seen) > self._window:
            self._seen_set.discard(self._seen.popleft())

    def _prune(self, latest: int) -> None:
        if len(self._missing) > self._window:
            self._missing = {s for s in self._missing if ((latest - s) & _MASK) <= self._window}

    def _reset_history(self) -> None:
        self._seen.clear()
        self._seen_set.clear()
        self._missing.clear()

    # ------------------------------------------------------------------------------------------ state
    @property
    def stats(self) -> ReceiverStats:
        """Counters (an immutable snapshot)."""
        return self._stats

    @property
    def latest(self) -> ReceivedFrame | None:
        """The newest accepted frame, or ``None`` before the first one."""
        return self._latest

    def now(self) -> float:
        """The receiver's clock [s] (arrivals and staleness)."""
        return self._clock()

    def status(self, now: float | None = None) -> StreamStatus:
        """``waiting``, ``live`` or ``stale`` at receiver time ``now`` (default: the clock)."""
        if self._latest is None:
            return StreamStatus.WAITING
        now = self._clock() if now is None else now
        return StreamStatus.STALE if now - self._latest.arrival > self._stale_after else StreamStatus.LIVE

    def frame_at(self, t: float | None = None) -> PoseFrame | None:
        """Poll, then the newest frame as a :class:`~wbcbench.teleop.PoseFrame` (``valid`` only when live).

        ``t`` is ignored (a live stream has only "now"); it is accepted so that a receiver can stand in for a
        recording as a pose source. Returns ``None`` before the first frame.
        """
        self.poll()
        latest = self._latest
        if latest is None:
            return None
        valid = self.status() is StreamStatus.LIVE
        return PoseFrame(latest.timestamp, dict(latest.positions), dict(latest.orientations), {}, valid)
