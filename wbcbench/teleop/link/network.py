"""Network realism for the operator's pose stream: one impairment model, used on two paths.

The model (`NetworkImpairment`, the parameters; `ImpairedLink`, the seeded state) decides, for each datagram the
operator sends at time t [s], whether and when it arrives, and in how many copies:

* stall: the sender sends nothing during each `stalls` window (start, duration) [s] of its own clock (a frozen
  suit driver, a busy operator PC): nothing leaves, nothing arrives;
* loss: independent (Bernoulli) with probability `loss`, or in bursts when `burst` (mean burst length in
  datagrams, >= 1) is given: the two-state Gilbert model (Gilbert 1960; every datagram in the bad state is lost)
  with P(good -> bad) = loss / (burst (1 - loss)), P(bad -> good) = 1 / burst, so that the long-run loss rate is
  still `loss`;
* delay: `latency` + a normal draw of standard deviation `jitter`, never below zero (with a jitter comparable to
  the frame interval, datagrams overtake each other as on a real network);
* reordering: with probability `reorder` a datagram is held back by a further `reorder_delay` (default 30 ms,
  1.5 frames at 50 Hz): the next ones overtake it;
* duplication: with probability `duplicate` a second copy arrives 1 ms after the first;
* corruption: with probability `corrupt` one byte of the datagram is flipped (garbage the receiver must reject).

Every datagram draws the same random numbers whatever the parameters, so with one seed the loss pattern of a
0 ms and of a 100 ms link are the same datagrams: tables over latency compare like with like.

The two paths, one model:

* sockets (`ImpairedRelay`): a UDP relay on the loopback interface between a sender and a `UdpPoseReceiver`;
  datagrams are impaired on the relay's wall clock (seconds since it started) and sent on when due;
* simulated time (`ImpairedReplay`): a recording replayed through the link in the run's own time, no socket,
  no wall clock: frame i is sent at (t_i - start) / speed, encoded as the stream's datagrams, and fed at its
  arrival time into a socket-less `UdpPoseReceiver` (the live stream's own decoder and sequence logic); at run
  time t the reference source sees what a live receiver would hold. Deterministic: tests and tables repeat.

`parse_impairment("latency=50ms,jitter=5ms,loss=5%,seed=1")` reads the command line's `--net` (and the `network`
scenario param); a bad spec is a one-line `ConfigError`.
"""

from __future__ import annotations

import heapq
import math
import re
import select
import socket
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from ...errors import ConfigError
from .receiver import UdpPoseReceiver
from ..io.recording import MocapRecording, PoseFrame
from ..io.segments import MVN_SEGMENT_IDS
from .sender import _check_loopback, recording_datagram

__all__ = ["NET_KEYS", "ImpairedLink", "ImpairedRelay", "ImpairedReplay", "LinkStats", "NetworkImpairment",
           "parse_impairment"]

#: delay of a duplicate after the original [s]
DUPLICATE_GAP = 1e-3


@dataclass(frozen=True)
class NetworkImpairment:
    """What the link does to the stream (module docstring). Times in s, probabilities in [0, 1].

    Raises:
        ConfigError: a value out of range (the key is named).
    """

    latency: float = 0.0
    jitter: float = 0.0
    loss: float = 0.0
    burst: float | None = None
    reorder: float = 0.0
    reorder_delay: float = 0.03
    duplicate: float = 0.0
    corrupt: float = 0.0
    stalls: tuple[tuple[float, float], ...] = ()
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("latency", "jitter", "reorder_delay"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ConfigError(f"must be a duration >= 0, got {v!r}", key=name)
        for name in ("loss", "reorder", "duplicate", "corrupt"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0.0 <= v <= 1.0):
                raise ConfigError(f"must be a probability in [0, 1] (or 0-100 %), got {v!r}", key=name)
        if self.loss >= 1.0:
            raise ConfigError("must be below 100 % (nothing would arrive)", key="loss")
        if self.burst is not None:
            b = self.burst
            if not (isinstance(b, (int, float)) and math.isfinite(b) and b >= 1.0):
                raise ConfigError(f"mean burst length must be >= 1 datagram, got {b!r}", key="burst")
            if self.loss / (b * (1.0 - self.loss)) > 1.0:
                raise ConfigError(f"a mean burst of {b:g} cannot give {100 * self.loss:g} % loss "
                                  f"(needs burst >= {self.loss / (1 - self.loss):.3g})", key="burst")
        for s in self.stalls:
            if len(s) != 2 or not all(math.isfinite(x) and x >= 0 for x in s):
                raise ConfigError(f"a stall is (start >= 0, duration >= 0) in s, got {s!r}", key="stall")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"must be an integer >= 0, got {self.seed!r}", key="seed")

    @property
    def is_ideal(self) -> bool:
        """True when the link changes nothing."""
        return self == NetworkImpairment(seed=self.seed)

    def describe(self) -> str:
        """The spec back in `parse_impairment`'s syntax (only the non-default keys)."""
        parts = []
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in ("stalls", "seed") or v == f.default:
                continue
            if f.name in ("latency", "jitter", "reorder_delay"):
                parts.append(f"{f.name}={1e3 * v:g}ms")
            elif f.name == "burst":
                parts.append(f"burst={v:g}")
            else:
                parts.append(f"{f.name}={100 * v:g}%")
        parts += [f"stall={d:g}s@{s:g}s" for s, d in self.stalls]
        parts.append(f"seed={self.seed}")
        return ",".join(parts)


#: `parse_impairment` keys: NetworkImpairment fields, `stall` (repeatable) for `stalls`
NET_KEYS = ("latency", "jitter", "loss", "burst", "reorder", "reorder_delay", "duplicate", "corrupt", "stall",
            "seed")
_DURATION = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(ms|s)?\s*$")


def _duration(text: str, key: str, where: str) -> float:
    m = _DURATION.match(text)
    if not m:
        raise ConfigError(f"{key}={text!r} is not a duration (e.g. 50ms, 0.05s, 0.05)", key=where)
    v = float(m.group(1))
    return v * 1e-3 if m.group(2) == "ms" else v


def _probability(text: str, key: str, where: str) -> float:
    s = text.strip()
    try:
        v = float(s[:-1]) / 100.0 if s.endswith("%") else float(s)
    except ValueError:
        raise ConfigError(f"{key}={text!r} is not a probability (e.g. 5%, 0.05)", key=where) from None
    if not (0.0 <= v <= 1.0):
        raise ConfigError(f"{key}={text!r} is not in 0-100 %", key=where)
    return v


def parse_impairment(spec: str | Mapping | NetworkImpairment | None, where: str = "--net") -> NetworkImpairment:
    """`"latency=50ms,jitter=5ms,loss=5%,burst=3,reorder=2%,duplicate=1%,corrupt=1%,stall=0.5s@3s,seed=1"` (or a
    mapping of the same keys, or a `NetworkImpairment`) -> `NetworkImpairment`. Durations: `ms`, `s` or plain
    seconds; probabilities: `%` or a fraction; `stall=DURATION@START`, repeatable; "" or "none": an ideal link.

    Raises:
        ConfigError: unknown key, bad value; one line naming `where` (the option or param).
    """
    if isinstance(spec, NetworkImpairment):
        return spec
    if spec is None:
        return NetworkImpairment()
    if isinstance(spec, Mapping):
        items = [(str(k), str(v)) for k, v in spec.items()]
    elif isinstance(spec, str):
        items = []
        text = spec.strip()
        if text.lower() in ("", "none", "ideal"):
            return NetworkImpairment()
        for part in text.split(","):
            key, eq, value = part.partition("=")
            if not eq or not key.strip() or not value.strip():
                raise ConfigError(f"'{part.strip()}' is not KEY=VALUE; keys: {', '.join(NET_KEYS)}", key=where)
            items.append((key.strip(), value.strip()))
    else:
        raise ConfigError(f"must be a string like latency=50ms,loss=5%, got {type(spec).__name__}", key=where)
    values: dict = {}
    stalls = []
    for key, value in items:
        if key not in NET_KEYS:
            from ...errors import did_you_mean

            raise ConfigError(f"unknown key '{key}'{did_you_mean(key, NET_KEYS)}; keys: {', '.join(NET_KEYS)}",
                              key=where)
        if key == "stall":
            dur, at, start = value.partition("@")
            if not at:
                raise ConfigError(f"stall={value!r} is not DURATION@START (e.g. 0.5s@3s)", key=where)
            stalls.append((_duration(start, "stall start", where), _duration(dur, "stall", where)))
            continue
        if key in values:
            raise ConfigError(f"key '{key}' given twice", key=where)
        if key in ("latency", "jitter", "reorder_delay"):
            values[key] = _duration(value, key, where)
        elif key == "burst":
            try:
                values[key] = float(value)
            except ValueError:
                raise ConfigError(f"burst={value!r} is not a mean burst length in datagrams (e.g. 3)",
                                  key=where) from None
        elif key == "seed":
            if not value.isdigit():
                raise ConfigError(f"seed={value!r} is not an integer >= 0", key=where)
            values[key] = int(value)
        else:
            values[key] = _probability(value, key, where)
    try:
        return NetworkImpairment(**values, stalls=tuple(stalls))
    except ConfigError as exc:
        raise ConfigError(f"{exc.key}: {str(exc).split(': ', 1)[-1]}", key=where) from None


@dataclass
class LinkStats:
    """What the link did, in datagrams: offered by the sender, held back by a stall, lost, delivered (copies
    included), duplicated, held back for reordering, corrupted."""

    offered: int = 0
    stalled: int = 0
    lost: int = 0
    delivered: int = 0
    duplicated: int = 0
    reordered: int = 0
    corrupted: int = 0

    def as_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


class ImpairedLink:
    """The seeded state of one impaired link (Gilbert state, random stream, counters)."""

    def __init__(self, impairment: NetworkImpairment):
        self.impairment = impairment
        self._rng = np.random.default_rng(impairment.seed)
        self._bad = False
        self.stats = LinkStats()

    def stalled(self, t: float) -> bool:
        """True when the sender is stalled at its time t [s]."""
        return any(s <= t < s + d for s, d in self.impairment.stalls)

    def transmit(self, t: float, data: bytes) -> list[tuple[float, bytes]]:
        """The datagram `data` sent at time t [s] -> its arrivals [(time [s], bytes)], in arrival order; [] when
        it is lost or the sender is stalled."""
        imp = self.impairment
        # the same draws for every datagram, whatever the parameters (module docstring)
        u_loss, u_reorder, u_dup, u_corrupt, u_byte, u_bit = self._rng.random(6)
        z1, z2 = self._rng.standard_normal(2)
        st = self.stats
        if self.stalled(t):
            st.stalled += 1
            return []
        st.offered += 1
        if imp.burst is None:
            lost = u_loss < imp.loss
        else:  # Gilbert: the state moves, then a datagram in the bad state is lost
            p_gb = imp.loss / (imp.burst * (1.0 - imp.loss))
            self._bad = (u_loss >= 1.0 / imp.burst) if self._bad else (u_loss < p_gb)
            lost = self._bad
        if lost:
            st.lost += 1
            return []
        if u_corrupt < imp.corrupt:
            b = bytearray(data)
            b[int(u_byte * len(b)) % len(b)] ^= 1 << int(u_bit * 8)
            data = bytes(b)
            st.corrupted += 1
        arrival = t + max(imp.latency + imp.jitter * z1, 0.0)
        if u_reorder < imp.reorder:
            arrival += imp.reorder_delay
            st.reordered += 1
        out = [(arrival, data)]
        if u_dup < imp.duplicate:
            out.append((max(t + max(imp.latency + imp.jitter * z2, 0.0), arrival) + DUPLICATE_GAP, data))
            st.duplicated += 1
        st.delivered += len(out)
        return out


class ImpairedReplay:
    """A recording sent through an `ImpairedLink` in simulated time (module docstring): a pose source whose
    `frame_at(t)` is what a live receiver holds at run time t [s].

    Args:
        recording: what the operator does.
        impairment: the link.
        speed: replay speed (frame i is sent at (times[i] - start) / speed).
        start: recording time [s] of the run's t = 0 (default the first frame).
        stale_after: the receiver's staleness timeout [s].
    """

    def __init__(self, recording: MocapRecording, impairment: NetworkImpairment, *, speed: float = 1.0,
                 start: float | None = None, stale_after: float = 0.2,
                 segment_ids: Mapping[str, int] = MVN_SEGMENT_IDS):
        self.recording = recording
        self.link = ImpairedLink(impairment)
        self.speed = float(speed)
        self.start = float(recording.times[0]) if start is None else float(start)
        self._now = 0.0
        self.receiver = UdpPoseReceiver(None, stale_after=stale_after, segment_ids=segment_ids,
                                        clock=lambda: self._now)
        self._times = np.asarray(recording.times, dtype=float)
        self._segment_ids = segment_ids
        self._next_frame = int(np.searchsorted(self._times, self.start - 1e-9))
        self._queue: list = []  # (arrival, order, datagram)
        self._order = 0

    @property
    def source(self) -> str:
        return self.recording.source

    @property
    def in_flight(self) -> int:
        """Datagrams sent and not arrived yet."""
        return len(self._queue)

    def sender_time(self, t: float) -> float:
        """The recording time being sent at run time t [s] (the shared clock of the simulated link)."""
        return self.start + t * self.speed

    def advance(self, t: float) -> int:
        """Send the frames due by run time t [s] through the link, and feed the receiver every datagram arrived
        by then, in arrival order; returns how many arrived."""
        times = self._times
        while self._next_frame < len(times) and (times[self._next_frame] - self.start) / self.speed <= t + 1e-12:
            i = self._next_frame
            t_send = (times[i] - self.start) / self.speed
            for arrival, data in self.link.transmit(t_send, recording_datagram(self.recording, i, i,
                                                                                self._segment_ids)):
                heapq.heappush(self._queue, (arrival, self._order, data))
                self._order += 1
            self._next_frame += 1
        n = 0
        while self._queue and self._queue[0][0] <= t + 1e-12:
            arrival, _, data = heapq.heappop(self._queue)
            self._now = arrival
            self.receiver.feed(data, arrival=arrival)
            n += 1
        self._now = t
        return n

    def frame_at(self, t: float) -> PoseFrame | None:
        """The newest frame the receiver holds at run time t [s] (`valid` only while the stream is live)."""
        self.advance(t)
        return self.receiver.frame_at(t)

    def close(self) -> None:
        self.receiver.close()


class ImpairedRelay:
    """A UDP relay on the loopback interface that impairs what passes: datagrams received on `listen`
    (host, port) go through an `ImpairedLink` on the relay's wall clock (s since `start()`) and are sent on to
    `forward` (a loopback address) when due. Runs in a daemon thread; `close()` stops it.

    Raises:
        ConfigError: `forward` is not a loopback address, or `listen` cannot be bound.
    """

    def __init__(self, impairment: NetworkImpairment, forward: tuple[str, int], listen: tuple[str, int] =
                 ("127.0.0.1", 0)):
        self.link = ImpairedLink(impairment)
        self.forward = (_check_loopback(forward[0]), int(forward[1]))
        self._rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._rx.bind((listen[0], int(listen[1])))
        except (OSError, OverflowError) as exc:
            self._rx.close()
            raise ConfigError(f"cannot bind UDP {listen[0]}:{listen[1]} ({getattr(exc, 'strerror', None) or exc})",
                              key="port") from None
        self._rx.setblocking(False)
        self._tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._queue: list = []
        self._count = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._t0: float | None = None
        self.forwarded = 0

    @property
    def port(self) -> int:
        """The port the relay listens on (send the stream here)."""
        return int(self._rx.getsockname()[1])

    def start(self) -> "ImpairedRelay":
        self._t0 = time.monotonic()
        self._thread = threading.Thread(target=self._run, daemon=True, name="wbcbench-net-relay")
        self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.is_set():
            now = time.monotonic() - self._t0
            while self._queue and self._queue[0][0] <= now:
                _, _, data = heapq.heappop(self._queue)
                try:
                    self._tx.sendto(data, self.forward)
                    self.forwarded += 1
                except OSError:
                    pass
            wait = min(self._queue[0][0] - now, 0.01) if self._queue else 0.01
            try:
                ready, _, _ = select.select([self._rx], [], [], max(wait, 0.0))
            except (OSError, ValueError):  # closed under us
                return
            if not ready:
                continue
            for _ in range(256):
                try:
                    data = self._rx.recv(65536)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError:
                    return
                t = time.monotonic() - self._t0
                for arrival, out in self.link.transmit(t, data):
                    heapq.heappush(self._queue, (arrival, self._count, out))
                    self._count += 1

    def close(self) -> None:
        """Stop the thread and close the sockets (idempotent); datagrams still queued are dropped."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(1.0)
            self._thread = None
        self._rx.close()
        self._tx.close()

    def __enter__(self) -> "ImpairedRelay":
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
