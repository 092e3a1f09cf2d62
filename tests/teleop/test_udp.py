"""Pose-stream datagrams and the loopback UDP receiver / replay sender: loss, reordering, duplicates, malformed
datagrams, staleness, wrap-around. Real datagrams on 127.0.0.1, bounded loops with deadlines."""

from __future__ import annotations

import socket
import struct
import time
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.errors import ConfigError
from wbcbench.teleop import (
    DatagramError,
    ReplaySender,
    StreamStatus,
    UdpPoseReceiver,
    decode_datagram,
    encode_datagram,
)
from wbcbench.teleop.protocol import HEADER, SEGMENT, TRAILER
from wbcbench.teleop.segments import MVN_SEGMENT_IDS

from .conftest import make_recording

DEADLINE = 2.0  # s, upper bound on any wait for loopback datagrams


def _poses(n: int = 3, seed: int = 0):
    rng = np.random.default_rng(seed)
    out = {}
    for seg_id in range(1, n + 1):
        q = rng.normal(size=4)
        out[seg_id] = (rng.normal(size=3), q / np.linalg.norm(q))
    return out


def _wait(receiver: UdpPoseReceiver, done) -> None:
    """Poll until ``done(receiver)`` or the deadline (then fail)."""
    end = time.monotonic() + DEADLINE
    while not done(receiver):
        if time.monotonic() > end:
            pytest.fail(f"timed out waiting for datagrams; stats {receiver.stats}")
        receiver.poll()
        time.sleep(0.001)


@pytest.fixture
def receiver():
    with UdpPoseReceiver(port=0, stale_after=0.2) as r:
        yield r


@pytest.fixture
def sock():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    yield s
    s.close()


# -------------------------------------------------------------------------------------------------- format
@settings(max_examples=50, deadline=None)
@given(seq=st.integers(0, 2**32 - 1), t=st.floats(-1e6, 1e6), n=st.integers(1, 48), seed=st.integers(0, 1000))
def test_encode_decode_round_trip(seq, t, n, seed):
    poses = _poses(n, seed)
    data = encode_datagram(seq, t, poses)
    assert len(data) == HEADER.size + n * SEGMENT.size + TRAILER.size == 24 + 30 * n
    d = decode_datagram(data)
    assert d.sequence == seq and d.timestamp == t and set(d.poses) == set(poses)
    for k, (p, q) in poses.items():
        np.testing.assert_allclose(d.poses[k][0], p, rtol=1e-6, atol=1e-6)  # float32 on the wire
        np.testing.assert_allclose(np.abs(d.poses[k][1] @ q), 1.0, atol=1e-6)


def test_layout_is_the_documented_one():
    data = encode_datagram(7, 1.5, {13: ((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0))})
    assert data[:4] == b"WBCP" and data[4] == 1 and data[5] == 0
    assert struct.unpack_from("<HId", data, 6) == (1, 7, 1.5)
    assert struct.unpack_from("<H3f4f", data, 20) == (13, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0)
    assert struct.unpack_from("<I", data, 50)[0] == zlib.crc32(data[:50])


@settings(max_examples=200, deadline=None)
@given(data=st.binary(max_size=200))
def test_random_bytes_only_ever_raise_datagram_error(data):
    try:
        decode_datagram(data)
    except DatagramError:
        pass


def test_every_single_bit_flip_is_detected():
    data = bytearray(encode_datagram(3, 0.25, _poses(2)))
    for bit in range(len(data) * 8):
        flipped = bytearray(data)
        flipped[bit // 8] ^= 1 << (bit % 8)
        with pytest.raises(DatagramError):
            decode_datagram(bytes(flipped))


@pytest.mark.parametrize(
    ("mutate", "reason"),
    [
        (lambda d: d[:10], "too short"),
        (lambda d: b"XXXX" + d[4:], "bad magic"),
        (lambda d: d[:4] + b"\x02" + d[5:], "version"),
        (lambda d: d[:-4] + b"\x00\x00\x00\x00", "CRC"),
        (lambda d: d + b"\x00", "size"),
    ],
)
def test_malformed_datagrams(mutate, reason):
    with pytest.raises(DatagramError, match=reason):
        decode_datagram(mutate(encode_datagram(1, 0.0, _poses(2))))


def test_encoder_refuses_bad_input():
    with pytest.raises(DatagramError):
        encode_datagram(-1, 0.0, _poses(1))
    with pytest.raises(DatagramError):
        encode_datagram(0, 0.0, {})
    with pytest.raises(DatagramError):
        encode_datagram(0, 0.0, {1: ((np.nan, 0, 0), (0, 0, 0, 1))})


def _raw(seq: int, poses, t: float = 0.0, *, nan: bool = False, dup_id: bool = False) -> bytes:
    """Hand-built datagram (valid CRC) for contents the encoder refuses."""
    items = list(poses.items())
    if dup_id:
        items.append(items[0])
    body = HEADER.pack(b"WBCP", 1, 0, len(items), seq, t)
    for seg_id, (p, q) in items:
        p = (np.nan, 0.0, 0.0) if nan else p
        body += SEGMENT.pack(seg_id, *p, *q)
    return body + TRAILER.pack(zlib.crc32(body))


# ---------------------------------------------------------------------------------------- sequence logic
def test_loss_reorder_duplicates_are_counted(receiver):
    poses = _poses(2)
    for seq in (0, 1, 2, 5, 3, 3, 6, 4, 2):
        receiver.feed(encode_datagram(seq, seq * 0.01, poses), arrival=0.0)
    st = receiver.stats
    assert (st.received, st.accepted, st.lost, st.reordered, st.duplicates, st.malformed) == (9, 5, 0, 2, 2, 0)
    assert receiver.latest.sequence == 6 and receiver.latest.timestamp == pytest.approx(0.06)


def test_loss_stays_counted_when_nothing_comes_back(receiver):
    for seq in (10, 11, 15, 16):
        receiver.feed(encode_datagram(seq, 0.0, _poses(1)), arrival=0.0)
    assert receiver.stats.lost == 3 and receiver.stats.accepted == 4


def test_sequence_wraps_around(receiver):
    for seq in (2**32 - 2, 2**32 - 1, 0, 1):
        receiver.feed(encode_datagram(seq, 0.0, _poses(1)), arrival=0.0)
    st = receiver.stats
    assert st.accepted == 4 and st.lost == 0 and st.reordered == 0 and st.restarts == 0
    assert receiver.latest.sequence == 1


def test_sender_restart_is_accepted(receiver):
    for seq in (5000, 5001, 0, 1):
        receiver.feed(encode_datagram(seq, 0.0, _poses(1)), arrival=0.0)
    st = receiver.stats
    assert st.restarts == 1 and st.accepted == 4 and receiver.latest.sequence == 1


def test_unknown_segment_ids_are_ignored(receiver):
    poses = {MVN_SEGMENT_IDS["LeftHand"]: ((0.1, 0.2, 0.3), (0, 0, 0, 1.0)), 999: ((0, 0, 0), (0, 0, 0, 1.0))}
    receiver.feed(encode_datagram(0, 0.0, poses), arrival=0.0)
    assert set(receiver.latest.positions) == {"LeftHand"}
    assert receiver.stats.unknown_segments == 1


def test_staleness_with_an_injected_clock():
    now = [0.0]
    with UdpPoseReceiver(stale_after=0.2, clock=lambda: now[0]) as r:
        assert r.status() is StreamStatus.WAITING and r.frame_at(0.0) is None
        r.feed(encode_datagram(0, 0.0, _poses(1)))
        now[0] = 0.15
        assert r.status() is StreamStatus.LIVE and r.frame_at(0.0).valid
        now[0] = 0.25
        assert r.status() is StreamStatus.STALE and not r.frame_at(0.0).valid
        r.feed(encode_datagram(0, 0.0, _poses(1)))  # a duplicate does not refresh liveness
        assert r.status() is StreamStatus.STALE
        r.feed(encode_datagram(1, 0.01, _poses(1)))
        assert r.status() is StreamStatus.LIVE


# ------------------------------------------------------------------------------------------- real sockets
def test_real_datagrams_in_order_then_lost_reordered_duplicated(receiver, sock):
    address = ("127.0.0.1", receiver.port)
    poses = _poses(3)
    for seq in range(10):
        sock.sendto(encode_datagram(seq, seq / 100, poses), address)
    _wait(receiver, lambda r: r.stats.received >= 10)
    assert receiver.stats.accepted == 10 and receiver.stats.lost == 0
    for seq in (12, 10, 10, 13, 11):  # 10 and 11 late, 10 twice
        sock.sendto(encode_datagram(seq, seq / 100, poses), address)
    _wait(receiver, lambda r: r.stats.received >= 15)
    st = receiver.stats
    assert (st.accepted, st.lost, st.reordered, st.duplicates) == (12, 0, 2, 1)
    assert receiver.latest.sequence == 13
    assert receiver.status() is StreamStatus.LIVE


def test_real_malformed_datagrams_are_counted_not_raised(receiver, sock):
    address = ("127.0.0.1", receiver.port)
    good = encode_datagram(0, 0.0, _poses(2))
    junk = [b"", b"hello", good[:-1], b"XXXX" + good[4:], _raw(1, _poses(2), nan=True),
            _raw(2, _poses(2), dup_id=True), bytes(len(good))]
    for data in junk:
        sock.sendto(data, address)
    sock.sendto(good, address)
    _wait(receiver, lambda r: r.stats.received >= len(junk) + 1)
    st = receiver.stats
    assert st.malformed == len(junk) and st.accepted == 1 and st.last_error
    assert receiver.latest.sequence == 0


def test_stream_goes_stale_after_the_timeout(sock):
    with UdpPoseReceiver(stale_after=0.05) as r:
        sock.sendto(encode_datagram(0, 0.0, _poses(1)), ("127.0.0.1", r.port))
        _wait(r, lambda rr: rr.stats.accepted >= 1)
        assert r.status() is StreamStatus.LIVE
        end = time.monotonic() + DEADLINE
        while r.status() is not StreamStatus.STALE and time.monotonic() < end:
            time.sleep(0.01)
        assert r.status() is StreamStatus.STALE
        assert time.monotonic() - r.latest.arrival > 0.05


def test_poll_never_blocks(receiver):
    start = time.monotonic()
    for _ in range(100):
        assert receiver.poll() == 0
    assert time.monotonic() - start < 0.5


# --------------------------------------------------------------------------------------------- replay sender
def test_replay_sender_streams_a_recording_at_a_speed_factor(receiver):
    rec = make_recording(n=26, rate=50.0)  # 0.5 s of recording, with MVN segment names
    with ReplaySender(rec, receiver.port, speed=10.0) as sender:
        start = time.monotonic()
        assert sender.run() == rec.n_frames
        elapsed = time.monotonic() - start
    assert 0.04 <= elapsed < 0.5  # 0.5 s of recording at 10x
    _wait(receiver, lambda r: r.stats.received >= rec.n_frames)
    st = receiver.stats
    assert st.accepted == rec.n_frames and st.lost == st.malformed == st.duplicates == 0
    frame = receiver.frame_at(0.0)
    assert frame.valid and frame.time == pytest.approx(rec.times[-1])
    for name in rec.segments:
        np.testing.assert_allclose(frame.positions[name], rec.position(name)[-1], atol=1e-5)


def test_replay_sender_in_the_background_can_be_stopped(receiver):
    rec = make_recording(n=200, rate=50.0)  # 4 s at 1x
    sender = ReplaySender(rec, receiver.port, speed=1.0, first_sequence=2**32 - 3)
    sender.start()
    _wait(receiver, lambda r: r.stats.accepted >= 5)
    sender.close()
    received = receiver.stats.accepted
    assert 5 <= received < rec.n_frames and receiver.stats.lost == 0  # wrapped past 2**32 - 1 without loss
    time.sleep(0.05)
    receiver.poll()
    assert receiver.stats.accepted <= sender.sent


@pytest.mark.parametrize("host", ["10.1.2.3", "0.0.0.0", "192.168.0.1"])
def test_replay_sender_refuses_non_loopback_hosts(host):
    with pytest.raises(ConfigError, match="loopback"):
        ReplaySender(make_recording(n=2), 9999, host=host)


def test_replay_sender_validates_its_arguments():
    rec = make_recording(n=2)
    with pytest.raises(ConfigError, match="speed"):
        ReplaySender(rec, 9999, speed=0.0)
    with pytest.raises(ConfigError, match="port"):
        ReplaySender(rec, 0)
    with pytest.raises(ConfigError, match="stale_after"):
        UdpPoseReceiver(stale_after=0.0)
