"""The pose-stream datagram: one UDP datagram per motion-capture frame.

Layout (all fields little-endian, no padding; ``struct`` formats in brackets)::

    offset  size  field
    ------  ----  ---------------------------------------------------------------------------------------
    header, 20 bytes  [<4sBBHId]
      0       4   magic            b"WBCP"
      4       1   version          1
      5       1   flags            0 (reserved; receivers ignore it)
      6       2   segment_count    n, 1..48
      8       4   sequence         uint32, +1 per frame, wraps 2**32 - 1 -> 0
     12       8   timestamp        float64 [s], the sender's time of the frame (recording time on replay)
    n segments, 30 bytes each  [<H3f4f]
      +0      2   segment_id       uint16, MVN segment number 1..23 (see MVN_SEGMENT_IDS); others ignored
      +2     12   position         3 x float32 [m], x y z in the sender's world frame
      +14    16   orientation      4 x float32, unit quaternion qx qy qz qw (scalar last)
    trailer, 4 bytes  [<I]
      20+30n  4   crc32            zlib.crc32 of every preceding byte of the datagram

    size = 24 + 30 n bytes: 714 bytes for the 23 MVN segments; n <= 48 keeps a datagram within one Ethernet
    frame (1472 bytes of UDP payload).

A datagram is *malformed*, and dropped, when it is shorter than 24 bytes, has the wrong magic, an unsupported
version, a size that disagrees with ``segment_count``, a bad CRC, a repeated segment id, non-finite numbers, or a
quaternion whose norm is not within 1 % of 1 (accepted ones are renormalised).
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Mapping
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ...errors import WbcError

__all__ = [
    "MAGIC",
    "VERSION",
    "HEADER",
    "SEGMENT",
    "TRAILER",
    "MAX_SEGMENTS",
    "Datagram",
    "DatagramError",
    "encode_datagram",
    "decode_datagram",
]

MAGIC = b"WBCP"
VERSION = 1
HEADER = struct.Struct("<4sBBHId")
SEGMENT = struct.Struct("<H3f4f")
TRAILER = struct.Struct("<I")
MAX_SEGMENTS = 48

FloatArray = npt.NDArray[np.float64]


class DatagramError(WbcError, ValueError):
    """A datagram that does not follow the format (the reason is the message)."""


class Datagram(NamedTuple):
    """A decoded datagram.

    Attributes:
        sequence: uint32 frame counter.
        timestamp: sender time of the frame [s].
        poses: segment id -> (position (3,) [m], quaternion (4,) x y z w, unit).
    """

    sequence: int
    timestamp: float
    poses: Mapping[int, tuple[FloatArray, FloatArray]]


def encode_datagram(
    sequence: int, timestamp: float, poses: Mapping[int, tuple[npt.ArrayLike, npt.ArrayLike]]
) -> bytes:
    """Pack one frame. ``poses``: segment id -> (position (3,) [m], quaternion (4,) x y z w).

    Raises:
        DatagramError: bad sequence, timestamp, segment count or id, or non-finite values.
    """
    if not 0 <= int(sequence) < 2**32:
        raise DatagramError(f"sequence must be in [0, 2**32), got {sequence}")
    if not math.isfinite(timestamp):
        raise DatagramError("timestamp must be finite")
    if not 1 <= len(poses) <= MAX_SEGMENTS:
        raise DatagramError(f"a datagram carries 1..{MAX_SEGMENTS} segments, got {len(poses)}")
    parts = [HEADER.pack(MAGIC, VERSION, 0, len(poses), int(sequence), float(timestamp))]
    for seg_id, (position, quaternion) in poses.items():
        if not 0 <= int(seg_id) < 2**16:
            raise DatagramError(f"segment id must be in [0, 65536), got {seg_id}")
        p = np.asarray(position, dtype=float).reshape(3)
        q = np.asarray(quaternion, dtype=float).reshape(4)
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
            raise DatagramError(f"segment {seg_id}: non-finite pose")
        parts.append(SEGMENT.pack(int(seg_id), *p, *q))
    body = b"".join(parts)
    return body + TRAILER.pack(zlib.crc32(body))


def decode_datagram(data: bytes) -> Datagram:
    """Unpack and validate one datagram (see the module docstring for what is malformed).

    Raises:
        DatagramError: the datagram is malformed; the message says why.
    """
    if len(data) < HEADER.size + TRAILER.size:
        raise DatagramError(f"too short ({len(data)} bytes)")
    magic, version, _flags, count, sequence, timestamp = HEADER.unpack_from(data, 0)
    if magic != MAGIC:
        raise DatagramError(f"bad magic {magic!r}")
    if version != VERSION:
        raise DatagramError(f"unsupported version {version}")
    expected = HEADER.size + count * SEGMENT.size + TRAILER.size
    if count < 1 or count > MAX_SEGMENTS or len(data) != expected:
        raise DatagramError(f"size {len(data)} bytes does not match segment_count {count}")
    (crc,) = TRAILER.unpack_from(data, expected - TRAILER.size)
    if crc != zlib.crc32(data[: expected - TRAILER.size]):
        raise DatagramError("CRC mismatch")
    if not math.isfinite(timestamp):
        raise DatagramError("non-finite timestamp")
    poses: dict[int, tuple[FloatArray, FloatArray]] = {}
    for k in range(count):
        seg_id, *values = SEGMENT.unpack_from(data, HEADER.size + k * SEGMENT.size)
        if seg_id in poses:
            raise DatagramError(f"segment id {seg_id} repeated")
        v = np.array(values, dtype=float)
        if not np.all(np.isfinite(v)):
            raise DatagramError(f"segment {seg_id}: non-finite pose")
        q = v[3:]
        norm = float(np.linalg.norm(q))
        if abs(norm - 1.0) > 1e-2:
            raise DatagramError(f"segment {seg_id}: quaternion norm {norm:.3g} is not 1")
        poses[seg_id] = (v[:3], q / norm)
    return Datagram(int(sequence), float(timestamp), poses)
