"""Fuzzing of the motion-capture readers (BVH, MVNX, pose CSV) and of the UDP datagram decoder: mutations of valid
files and datagrams, random bytes. Each input is read or refused with a WbcError (one line at the command line),
never another exception. Derandomized, bounded counts."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wbcbench.errors import WbcError
from wbcbench.teleop import load_recording, write_mvnx, write_pose_csv
from wbcbench.teleop.protocol import decode_datagram, encode_datagram
from wbcbench.teleop.registry import RECORDINGS_DIR

RECORDINGS = RECORDINGS_DIR


def fuzz(n):
    return settings(max_examples=n, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                           HealthCheck.data_too_large])


TOKENS = st.sampled_from(["", "nan", "inf", "-1e309", "1e400", "0", "-0", "abc", "{", "}", "JOINT", "End Site",
                          "CHANNELS 6 Xposition", "OFFSET", "Frames: -3", "Frame Time: 0", "MOTION", "ROOT x",
                          "<frame>", "</segment>", "<mvnx>", "&", "1,2", ",,,,", "\t", "\x00", "9" * 40])


@st.composite
def mutated_text(draw, text: str):
    lines = text.splitlines()
    for _ in range(draw(st.integers(1, 4))):
        if not lines:
            break
        i = draw(st.integers(0, len(lines) - 1))
        op = draw(st.sampled_from(["delete", "replace", "insert", "token", "truncate", "duplicate"]))
        if op == "delete":
            del lines[i]
        elif op == "replace":
            lines[i] = draw(st.text(max_size=40))
        elif op == "insert":
            lines.insert(i, draw(TOKENS))
        elif op == "token":
            words = lines[i].split()
            if words:
                words[draw(st.integers(0, len(words) - 1))] = draw(TOKENS)
                lines[i] = " ".join(words)
        elif op == "truncate":
            lines = lines[:i]
        else:
            lines.insert(i, lines[i])
    return "\n".join(lines) + ("\n" if draw(st.booleans()) else "")


def _check(path: Path, text: str) -> None:
    path.write_text(text, encoding="utf-8", errors="surrogateescape")
    try:
        load_recording(path)
    except WbcError as exc:
        assert str(exc) and "\n" not in str(exc).strip()


def _short(text: str, frames: int) -> str:
    """A recording cut to its first frames (the fuzzed inputs stay small and fast to read)."""
    head, _, motion = text.partition("MOTION")
    rows = motion.strip().splitlines()
    body = [r for r in rows if not r.startswith(("Frames:", "Frame Time:"))][:frames]
    return f"{head}MOTION\nFrames: {len(body)}\nFrame Time: 0.01\n" + "\n".join(body) + "\n"


BVH = _short((RECORDINGS / "reach_forward.bvh").read_text(), 6)


def test_fuzz_bvh(tmp_path):
    @fuzz(2500)
    @given(mutated_text(BVH))
    def run(text):
        _check(tmp_path / "f.bvh", text)

    run()


def _other_formats(tmp_path):
    rec = load_recording(tmp_path / "base.bvh") if (tmp_path / "base.bvh").write_text(BVH) else None
    return (write_mvnx(tmp_path / "base.mvnx", rec).read_text(), write_pose_csv(tmp_path / "base.csv", rec).read_text())


def test_fuzz_mvnx_and_csv(tmp_path):
    mvnx, csv = _other_formats(tmp_path)

    @fuzz(2000)
    @given(mutated_text(mvnx))
    def run_mvnx(text):
        _check(tmp_path / "f.mvnx", text)

    @fuzz(2000)
    @given(mutated_text(csv))
    def run_csv(text):
        _check(tmp_path / "f.csv", text)

    run_mvnx()
    run_csv()


@fuzz(1500)
@given(blob=st.binary(max_size=300), suffix=st.sampled_from([".bvh", ".mvnx", ".csv"]))
def test_fuzz_random_bytes(tmp_path_factory, blob, suffix):
    d = tmp_path_factory.mktemp("bytes")
    p = d / f"f{suffix}"
    p.write_bytes(blob)
    try:
        load_recording(p)
    except WbcError as exc:
        assert "\n" not in str(exc).strip()


GOOD = encode_datagram(7, 1.25, {0: ((0.1, 0.2, 0.3), (0.0, 0.0, 0.0, 1.0)), 3: ((1, 2, 3), (0, 0, 1, 0))})


@fuzz(6000)
@given(data=st.one_of(
    st.binary(max_size=200),
    st.tuples(st.integers(0, len(GOOD) - 1), st.integers(0, 255)).map(
        lambda iv: GOOD[:iv[0]] + bytes([iv[1]]) + GOOD[iv[0] + 1:]),
    st.integers(0, len(GOOD)).map(lambda n: GOOD[:n]),
    st.binary(min_size=1, max_size=40).map(lambda b: GOOD + b),
    st.tuples(st.integers(0, len(GOOD) - 5), st.floats(allow_nan=True)).map(  # a float patched in, CRC fixed
        lambda iv: _recrc(GOOD[:iv[0]] + struct.pack("<d", iv[1])[:4] + GOOD[iv[0] + 4:]))))
def test_fuzz_datagrams(data):
    try:
        d = decode_datagram(data)
    except WbcError as exc:
        assert str(exc) and "\n" not in str(exc)
        return
    assert np.isfinite(d.timestamp) and len(d.poses) >= 1


def _recrc(body_with_crc: bytes) -> bytes:
    body = body_with_crc[:-4]
    return body + struct.pack("<I", zlib.crc32(body))
