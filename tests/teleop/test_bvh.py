"""BVH: write then read, Euler channel orders, forward kinematics, corrupted and truncated files."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from wbcbench.errors import ConfigError
from wbcbench.teleop import BvhJoint, BvhSkeleton, load_recording, parse_bvh, read_bvh, write_bvh
from wbcbench.teleop._rotations import to_matrix

from .conftest import assert_one_line_error

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]


def _chain(order_root: str, order_joint: str) -> BvhSkeleton:
    return BvhSkeleton((
        BvhJoint("Hips", -1, (1.0, 2.0, 3.0),
                 ("Xposition", "Yposition", "Zposition", *(f"{a}rotation" for a in order_root))),
        BvhJoint("Spine", 0, (0.0, 10.0, 0.0), tuple(f"{a}rotation" for a in order_joint)),
        BvhJoint("LeftUpLeg", 0, (8.0, -5.0, 0.0), ("Zrotation", "Xrotation"), (0.0, -40.0, 0.0)),
        BvhJoint("Head", 1, (0.0, 20.0, 3.0), ("Yrotation",), (0.0, 10.0, 0.0)),
    ))  # fmt: skip


@settings(max_examples=20, deadline=None)
@given(
    root=st.sampled_from(ORDERS),
    joint=st.sampled_from(ORDERS),
    seed=st.integers(0, 2**32 - 1),
)
def test_write_read_round_trip_and_euler_orders(tmp_path_factory, root, joint, seed):
    rng = np.random.default_rng(seed)
    skeleton = _chain(root, joint)
    n = 5
    motion = rng.uniform(-170, 170, size=(n, skeleton.channel_count))
    motion[:, :3] = rng.uniform(-50, 50, size=(n, 3))
    path = tmp_path_factory.mktemp("bvh") / "chain.bvh"
    write_bvh(path, skeleton, motion, 1 / 60, decimals=6)
    data = parse_bvh(path)
    assert [j.name for j in data.skeleton.joints] == ["Hips", "Spine", "Head", "LeftUpLeg"]  # depth-first
    assert data.frame_time == pytest.approx(1 / 60)
    by_name = dict(zip(skeleton.channel_names, motion.T, strict=True))
    read_back = dict(zip(data.skeleton.channel_names, data.motion.T, strict=True))
    assert set(by_name) == set(read_back)
    for name in by_name:
        np.testing.assert_allclose(read_back[name], by_name[name], atol=1e-6)

    rec = read_bvh(path, length_unit=0.01)
    assert rec.frame_rate == pytest.approx(60.0)
    np.testing.assert_allclose(np.diff(rec.times), 1 / 60)
    assert rec.segments == ("Hips", "Spine", "Head", "LeftUpLeg")
    assert rec.parents == (-1, 0, 1, 0)
    # independent forward kinematics with scipy's intrinsic Euler sequences (upper case = intrinsic), on the
    # values as written (6 decimals)
    by_name = read_back
    for i in range(n):
        R_hips = Rotation.from_euler(root, [by_name[f"Hips:{a}rotation"][i] for a in root], degrees=True).as_matrix()
        p_hips = 0.01 * (np.array([1.0, 2.0, 3.0]) + [by_name[f"Hips:{a}position"][i] for a in "XYZ"])
        R_spine = R_hips @ Rotation.from_euler(
            joint, [by_name[f"Spine:{a}rotation"][i] for a in joint], degrees=True
        ).as_matrix()
        p_spine = p_hips + R_hips @ np.array([0.0, 0.1, 0.0])
        R_head = R_spine @ Rotation.from_euler("Y", by_name["Head:Yrotation"][i], degrees=True).as_matrix()
        p_head = p_spine + R_spine @ np.array([0.0, 0.2, 0.03])
        np.testing.assert_allclose(rec.positions[i, 0], p_hips, atol=1e-8)
        np.testing.assert_allclose(rec.positions[i, 1], p_spine, atol=1e-8)
        np.testing.assert_allclose(rec.positions[i, 2], p_head, atol=1e-8)
        np.testing.assert_allclose(to_matrix(rec.orientations[i, 1]), R_spine, atol=1e-8)
        np.testing.assert_allclose(to_matrix(rec.orientations[i, 2]), R_head, atol=1e-8)
    # joint angles are the rotation channels, in radians
    k = rec.joint_names.index("Head:Yrotation")
    np.testing.assert_allclose(rec.joint_angles[:, k], np.radians(by_name["Head:Yrotation"]), atol=1e-8)


def test_end_sites_and_units_survive(tmp_path):
    skeleton = _chain("ZXY", "ZXY")
    path = write_bvh(tmp_path / "a.bvh", skeleton, np.zeros((2, skeleton.channel_count)), 0.01)
    data = parse_bvh(path)
    head = next(j for j in data.skeleton.joints if j.name == "Head")
    assert head.end_site == (0.0, 10.0, 0.0)
    metres = read_bvh(path, length_unit=1.0)
    centimetres = load_recording(path, length_unit="cm")  # (the default detects it from a human skeleton)
    np.testing.assert_allclose(metres.positions * 0.01, centimetres.positions)


GOOD = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.02
0 90 0 0 0 0 10 0 0
0 90 0 0 0 0 20 0 0
0 90 0 0 0 0 30 0 0
"""


def _corrupt(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)


CORRUPTIONS = {
    "truncated motion": (GOOD.rsplit("\n", 2)[0] + "\n", "line 20", "3 frames declared, 2 found"),
    "truncated hierarchy": (GOOD.split("  JOINT")[0], "line 5", "no 'MOTION'"),
    "short frame": (_corrupt(GOOD, "0 90 0 0 0 0 20 0 0", "0 90 0 0 0 0 20 0"), "line 20", "8 values, expected 9"),
    "not a number": (_corrupt(GOOD, "0 90 0 0 0 0 30 0 0", "0 90 0 0 x 0 30 0 0"), "line 21", "'x'"),
    "bad channel": (_corrupt(GOOD, "Zrotation Xrotation Yrotation\n    End", "Zrotation Xrotation Wrotation\n    End"),
                    "line 9", "unknown channel 'Wrotation'"),
    "missing brace": (_corrupt(GOOD, "  JOINT Spine\n  {", "  JOINT Spine\n"), "line 8", "expected '{'"),
    "bad frame time": (_corrupt(GOOD, "Frame Time: 0.02", "Frame Time: 0"), "line 18", "Frame Time"),
    "bad frames count": (_corrupt(GOOD, "Frames: 3", "Frames: three"), "line 17", "'Frames:'"),
    "extra frame": (GOOD + "0 90 0 0 0 0 40 0 0\n", "line 22", "more motion lines"),
    "non finite": (_corrupt(GOOD, "0 90 0 0 0 0 30 0 0", "0 90 0 0 nan 0 30 0 0"), "line 21", "non-finite"),
    "bad offset": (_corrupt(GOOD, "OFFSET 0 10 0", "OFFSET 0 ten 0"), "line 8", "OFFSET"),
    "unexpected keyword": (_corrupt(GOOD, "    End Site", "    Bone Site"), "line 10", "'Bone'"),
    "empty": ("", "line 1", "MOTION"),
}


@pytest.mark.parametrize("case", sorted(CORRUPTIONS))
def test_corrupted_files_raise_one_line_errors_naming_file_and_line(tmp_path, case):
    text, line, fragment = CORRUPTIONS[case]
    path = tmp_path / "broken.bvh"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        read_bvh(path)
    assert_one_line_error(info, str(path), line, fragment)


def test_good_sample_reads(tmp_path):
    path = tmp_path / "good.bvh"
    path.write_text(GOOD)
    rec = read_bvh(path)
    assert rec.n_frames == 3 and rec.segments == ("Hips", "Spine")
    # root turned 0 deg; spine flexed about z by 10..30 deg; position offset 90 cm in y
    np.testing.assert_allclose(rec.positions[:, 0], [[0.0, 0.9, 0.0]] * 3)
    np.testing.assert_allclose(rec.joint_angles[:, rec.joint_names.index("Spine:Zrotation")], np.radians([10, 20, 30]))


def test_binary_and_missing_files(tmp_path):
    path = tmp_path / "binary.bvh"
    path.write_bytes(b"\xff\xfe\x00HIERARCHY")
    with pytest.raises(ConfigError) as info:
        read_bvh(path)
    assert_one_line_error(info, str(path), "not a text file")
    with pytest.raises(ConfigError) as info:
        read_bvh(tmp_path / "nope.bvh")
    assert_one_line_error(info, "nope.bvh", "cannot read")
