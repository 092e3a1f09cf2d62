"""Replay a recording as a live pose stream over loopback UDP.

The sender stamps each datagram with the recording time of the frame and numbers frames from
``first_sequence`` (uint32, wrapping). Frame ``i`` is due ``(times[i] - times[start]) / speed`` seconds after the
start. Only loopback destinations are allowed (the stream is a test and replay tool, not a network service).
"""

from __future__ import annotations

import ipaddress
import socket
import threading
import time
from collections.abc import Callable, Iterator, Mapping

from ...errors import ConfigError
from .protocol import MAX_SEGMENTS, encode_datagram
from ..io.recording import MocapRecording
from ..io.segments import MVN_SEGMENT_IDS

__all__ = ["ReplaySender", "recording_datagram"]


def _check_loopback(host: str) -> str:
    try:
        address = socket.gethostbyname(host)
    except OSError:
        raise ConfigError(f"cannot resolve host {host!r}", key="host") from None
    if not ipaddress.ip_address(address).is_loopback:
        raise ConfigError(f"host {host!r} ({address}) is not a loopback address; only 127.0.0.1 is allowed",
                          key="host")
    return address


def recording_datagram(recording: MocapRecording, index: int, sequence: int,
                       segment_ids: Mapping[str, int] = MVN_SEGMENT_IDS) -> bytes:
    """The stream's datagram of frame `index` of a recording: its segments with an id, the recording time as the
    time stamp, `sequence` (wrapped to uint32)."""
    poses = {int(segment_ids[name]): (recording.positions[index, k], recording.orientations[index, k])
             for k, name in enumerate(recording.segments) if name in segment_ids}
    return encode_datagram(sequence & 0xFFFFFFFF, float(recording.times[index]), poses)


class ReplaySender:
    """Stream a :class:`~wbcbench.teleop.MocapRecording` to ``host:port`` (loopback only).

    Args:
        recording: what to stream; its segments with an id in ``segment_ids`` are sent (others skipped).
        port: destination UDP port.
        host: destination, must resolve to a loopback address (default ``127.0.0.1``).
        speed: playback speed factor (> 0): 2 plays twice as fast.
        segment_ids: segment name -> id (default: MVN numbering).
        first_sequence: sequence number of the first datagram.

    Raises:
        ConfigError: non-loopback host, bad speed or port, or no segment of the recording has an id.
    """

    def __init__(
        self,
        recording: MocapRecording,
        port: int,
        host: str = "127.0.0.1",
        *,
        speed: float = 1.0,
        segment_ids: Mapping[str, int] = MVN_SEGMENT_IDS,
        first_sequence: int = 0,
    ) -> None:
        if not (speed > 0.0) or speed == float("inf"):
            raise ConfigError(f"speed must be a finite number > 0, got {speed!r}", key="speed")
        if not 0 < int(port) < 65536:
            raise ConfigError(f"port must be in 1..65535, got {port!r}", key="port")
        self._address = (_check_loopback(host), int(port))
        self._recording = recording
        self._speed = float(speed)
        self._segment_ids = dict(segment_ids)
        self._ids = [(k, int(segment_ids[name])) for k, name in enumerate(recording.segments) if name in segment_ids]
        if not self._ids:
            raise ConfigError("no segment of the recording has a stream id", file=recording.source or None)
        if len(self._ids) > MAX_SEGMENTS:
            raise ConfigError(f"at most {MAX_SEGMENTS} segments per datagram", file=recording.source or None)
        self._first_sequence = int(first_sequence) & 0xFFFFFFFF
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sent = 0
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    @property
    def sent(self) -> int:
        """Datagrams sent so far."""
        return self._sent

    @property
    def destination(self) -> tuple[str, int]:
        """(address, port) the datagrams go to."""
        return self._address

    def datagram(self, index: int, sequence: int | None = None) -> bytes:
        """The datagram of frame ``index`` (sequence ``first_sequence + index`` unless given)."""
        seq = (self._first_sequence + index) & 0xFFFFFFFF if sequence is None else sequence
        return recording_datagram(self._recording, index, seq, self._segment_ids)

    def datagrams(self, start: int = 0, stop: int | None = None) -> Iterator[tuple[float, bytes]]:
        """``(due time [s] after the start, datagram)`` for frames ``start .. stop - 1``."""
        rec = self._recording
        stop = rec.n_frames if stop is None else min(stop, rec.n_frames)
        for i in range(start, stop):
            yield (float(rec.times[i] - rec.times[start]) / self._speed, self.datagram(i))

    def send_raw(self, data: bytes) -> None:
        """Send arbitrary bytes to the destination (tests use it for malformed datagrams)."""
        self._sock.sendto(data, self._address)
        self._sent += 1

    def run(
        self,
        start: int = 0,
        stop: int | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> int:
        """Send frames ``start .. stop - 1`` in real time (scaled by ``speed``), blocking; returns the count.

        Stops early when :meth:`stop` is called from another thread.
        """
        t0 = clock()
        count = 0
        for due, data in self.datagrams(start, stop):
            if self._stop.is_set():
                break
            delay = t0 + due - clock()
            if delay > 0:
                sleep(delay)
            self.send_raw(data)
            count += 1
        return count

    def start(self, start: int = 0, stop: int | None = None) -> None:
        """Run :meth:`run` in a background thread (daemon)."""
        if self._thread is not None and self._thread.is_alive():
            raise RuntimeError("the sender is already running")
        self._stop.clear()
        self._thread = threading.Thread(target=self.run, args=(start, stop), daemon=True, name="wbcbench-replay")
        self._thread.start()

    def stop(self, timeout: float = 1.0) -> None:
        """Ask the background thread to stop and wait for it (at most ``timeout`` s)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None

    def close(self) -> None:
        """Stop streaming and close the socket."""
        self.stop()
        self._sock.close()

    def __enter__(self) -> "ReplaySender":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
