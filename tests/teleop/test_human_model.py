"""The human model: per-operator scaling, lengths estimated from a recording, posing from joint angles, fitting
to points, feet placement."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.errors import ConfigError
from wbcbench.teleop import HumanModel, MocapRecording, estimate_segment_lengths, open_recording, read_bvh, write_bvh
from wbcbench.teleop.human_model import LINKS, SKELETON
from wbcbench.teleop.synthetic import OPERATORS

SEEDS = st.integers(0, 2**32 - 1)
_BY_NAME = {s.name: s for s in SKELETON}


def _random_posture(human: HumanModel, rng, spread: float = 0.5) -> np.ndarray:
    q = human.neutral()
    q[7:] += rng.uniform(-spread, spread, size=human.model.nq - 7)
    q = human.clip(q)
    q[:3] = rng.uniform(-1, 1, size=3)
    q[3:7] = pin.Quaternion(pin.exp3(rng.normal(size=3))).coeffs()
    return q


def _link_lengths(human: HumanModel, q) -> dict[str, float]:
    points = human.keypoints(q, [s.name for s in SKELETON])
    return {link.name: float(np.linalg.norm(points[link.distal] - points[link.proximal])) for link in LINKS}


def test_default_lengths_are_the_example_robot_data_model():
    lengths = HumanModel.default_lengths()
    assert lengths["left_upper_arm"] == pytest.approx(0.276)
    assert lengths["left_thigh"] == pytest.approx(0.439)
    assert set(lengths) == {link.name for link in LINKS} and len(lengths) == 14


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_scaling_sets_every_length_whatever_the_posture(seed):
    rng = np.random.default_rng(seed)
    target = {k: v * rng.uniform(0.8, 1.25) for k, v in HumanModel.default_lengths().items()}
    human = HumanModel(target)
    assert human.lengths == pytest.approx(target)
    q = _random_posture(human, rng)
    q[human.model.idx_qs[human.model.getJointId("left_clavicle_joint_X")]] = 0.0  # the girdle links
    q[human.model.idx_qs[human.model.getJointId("right_clavicle_joint_X")]] = 0.0  # depend on the clavicle
    measured = _link_lengths(human, q)
    for name, value in target.items():
        assert measured[name] == pytest.approx(value, abs=1e-9), name


def test_lengths_estimated_from_a_noisy_recording(human):
    """A CSV-like recording (positions only, 5 mm noise per point) of a scaled operator in random postures."""
    rng = np.random.default_rng(4)
    truth = OPERATORS["C"].lengths()
    operator = HumanModel(truth)
    names = [s.name for s in SKELETON]
    n = 300
    positions = np.empty((n, len(names), 3))
    for i in range(n):
        points = operator.keypoints(_random_posture(operator, rng, spread=0.3), names)
        positions[i] = np.array([points[k] for k in names]) + rng.normal(scale=0.005, size=(len(names), 3))
    quats = np.tile([0.0, 0.0, 0.0, 1.0], (n, len(names), 1))
    rec = MocapRecording("noisy.csv", 60.0, np.arange(n) / 60.0, tuple(names), positions, quats)
    estimated = estimate_segment_lengths(rec)
    assert set(estimated) == set(truth)
    for name, value in truth.items():
        tol = 0.012 if "shoulder_girdle" in name else 0.003  # the girdle length moves with the clavicle angle
        assert estimated[name] == pytest.approx(value, abs=tol), name
    scaled = HumanModel.from_recording(rec)
    assert scaled.lengths == pytest.approx(estimated)


def test_shipped_recordings_give_their_operator_size():
    rec = open_recording("reach_sideways")  # operator B: every length x 0.93
    human = HumanModel.from_recording(rec)
    for name, value in OPERATORS["B"].lengths().items():
        assert human.lengths[name] == pytest.approx(value, abs=5e-4), name


def test_implausible_lengths_are_refused():
    with pytest.raises(ConfigError, match="wrong length unit"):
        HumanModel({"left_thigh": 43.9})  # centimetres read as metres
    with pytest.raises(ConfigError, match="unknown segment length"):
        HumanModel({"left_tibia": 0.4})
    rec = open_recording("arms_down")
    wrong_unit = read_bvh(rec.source, length_unit=1.0)  # the file is in centimetres
    with pytest.raises(ConfigError) as info:
        HumanModel.from_recording(wrong_unit)
    assert rec.source in str(info.value)


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS)
def test_posed_from_bvh_channels(tmp_path_factory, seed):
    rng = np.random.default_rng(seed)
    human = HumanModel(OPERATORS["B"].lengths())
    qs = np.array([_random_posture(human, rng, spread=1.0) for _ in range(3)])
    path = tmp_path_factory.mktemp("h") / "h.bvh"
    write_bvh(path, human.bvh_skeleton(), human.bvh_motion(qs), 0.02, decimals=6)
    rec = read_bvh(path)
    R0 = human.model.jointPlacements[1].rotation  # the BVH world is the y-up frame before the root rotation
    for i, q in enumerate(qs):
        q_back, used = human.configuration_from_frame(rec.frame(i))
        assert used == 36
        np.testing.assert_allclose(q_back[7:], q[7:], atol=1e-6)
        placements = human.placements(q)
        for k, name in enumerate(rec.segments):
            np.testing.assert_allclose(R0 @ rec.positions[i, k], placements[name].translation, atol=1e-6)


@settings(max_examples=5, deadline=None)
@given(seed=SEEDS)
def test_fit_recovers_the_keypoints(human, seed):
    rng = np.random.default_rng(seed)
    q_true = _random_posture(human, rng, spread=0.4)
    targets = human.keypoints(q_true)
    q0 = human.neutral()
    q0[:7] = q_true[:7]  # start from the right root placement, neutral joints
    result = human.fit(targets, q0)
    assert result.rms < 0.005, result


def test_feet_placement(human):
    target = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, 1.2), np.array([0.5, -0.3, 0.0]))
    rng = np.random.default_rng(0)
    q = _random_posture(human, rng, spread=0.2)
    placed = human.place_feet(q, target)
    np.testing.assert_allclose(human.feet_frame(placed).homogeneous, target.homogeneous, atol=1e-9)
    np.testing.assert_allclose(placed[7:], q[7:])  # only the root moved
    # standing straight, the soles are 8 cm under the ankles and the head 1.53 m above the floor
    standing = human.place_feet(human.neutral(), pin.SE3.Identity())
    points = human.keypoints(standing, ["LeftFoot", "Head"])
    assert points["LeftFoot"][2] == pytest.approx(0.08)
    assert points["Head"][2] == pytest.approx(1.532, abs=1e-3)
    assert human.shoulder_height() == pytest.approx(1.383, abs=1e-3)


def test_unknown_joint_in_angles(human):
    with pytest.raises(ConfigError, match="unknown human joint"):
        human.configuration_from_angles({"left_knee": 0.3})
    q, used = human.configuration_from_channels({"nonsense:x": 1.0})
    assert used == 0
    np.testing.assert_array_equal(q, human.neutral())


def test_the_feet_frame_of_a_stride_faces_the_hips():
    """Feet side by side: the heading is the feet's (right to left foot); feet in a stride (one 0.45 m ahead, as an
    operator caught mid-walk): the right-to-left foot direction points along the walk, so the heading is the
    hips'."""
    from wbcbench.teleop.human.model import STRIDE_ANGLE, feet_frame

    up = np.array([0.0, 0.0, 1.0])
    hips = np.array([0.05, 0.2, 0.0])  # the hips' left, turned 14 deg from +y
    side_by_side = feet_frame(np.array([0.0, 0.1, 0.0]), np.array([0.0, -0.1, 0.0]), up, up, hips_left=hips)
    np.testing.assert_allclose(side_by_side.rotation[:, 1], [0.0, 1.0, 0.0], atol=1e-12)  # the feet's
    stride = feet_frame(np.array([0.45, 0.05, 0.0]), np.array([0.0, -0.05, 0.0]), up, up, hips_left=hips)
    np.testing.assert_allclose(stride.rotation[:, 1], hips / np.linalg.norm(hips), atol=1e-12)
    np.testing.assert_allclose(stride.translation, [0.225, 0.0, 0.0])
    a = np.radians(STRIDE_ANGLE + 1.0)  # just past the angle: the hips'
    past = feet_frame(np.array([np.sin(a), np.cos(a), 0.0]), np.zeros(3), up, up, hips_left=np.array([0.0, 1.0, 0.0]))
    np.testing.assert_allclose(past.rotation[:, 1], [0.0, 1.0, 0.0], atol=1e-12)
    legacy = feet_frame(np.array([0.45, 0.05, 0.0]), np.array([0.0, -0.05, 0.0]), up, up)  # no hips: the feet's
    assert abs(legacy.rotation[0, 1]) > 0.9
