"""Retargeting to TALOS: arms-down targets near the robot's hands, calibration, invariance to the suit's world
frame, positions-only sources, validity, workspace clamping, a live stream end to end."""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.errors import ConfigError, WbcError
from wbcbench.side import Side
from wbcbench.tasks import RepulsionPoint, SelfCollisionTask, update_kinematics
from wbcbench.tasks.self_collision import attractor
from wbcbench.teleop import (
    EFFECTORS,
    HumanModel,
    MocapRecording,
    ReplaySender,
    Retargeter,
    UdpPoseReceiver,
    open_recording,
    robot_workspaces,
)
from wbcbench.teleop._rotations import from_matrix, to_matrix


@pytest.fixture(scope="module")
def arms_down() -> MocapRecording:
    return open_recording("arms_down")


@pytest.fixture(scope="module")
def workspaces(talos):
    return robot_workspaces(talos)


def _moved(rec: MocapRecording, R: np.ndarray, t: np.ndarray, *, angles: bool) -> MocapRecording:
    """The same motion seen in another suit world frame (and optionally without its joint angles)."""
    positions = rec.positions @ R.T + t
    orientations = from_matrix(R @ to_matrix(rec.orientations))
    return MocapRecording(
        source="moved", frame_rate=rec.frame_rate, times=rec.times, segments=rec.segments, parents=rec.parents,
        positions=positions, orientations=orientations,
        joint_names=rec.joint_names if angles else (), joint_angles=rec.joint_angles if angles else None,
    )


def test_arms_down_gives_hand_targets_near_the_robot_hands(talos, arms_down, workspaces):
    """Paper 004: with the arms along the body the operator's hands map into TALOS' hips, close to (medial of) the
    grippers of the reference posture. Measured: 0.25-0.32 m from the grippers, nearly all of it sideways."""
    r = Retargeter(talos, arms_down, workspaces=workspaces)
    cal = r.calibration
    assert cal.method == "joint_angles" and cal.rms < 1e-3
    assert 0.9 < cal.proportion < 1.2  # TALOS' shoulders / operator B's (1.67 m) shoulders
    for t in np.arange(0.0, arms_down.duration, 0.5):
        sample = r.sample(t)
        assert sample.valid and not any(sample.clamped.values())
        for side, sign in (("left_hand", 1.0), ("right_hand", -1.0)):
            target = sample.references[side].translation
            hand = r.reference_poses[side].translation
            assert np.linalg.norm(target - hand) < 0.35
            assert abs(target[2] - hand[2]) < 0.05  # same height
            assert abs(target[0] - hand[0]) < 0.20
            assert 0.1 < sign * target[1] < sign * hand[1]  # on its side, inside the gripper: in the hips


def test_calibration_instant_maps_orientations_onto_the_reference_posture(talos, arms_down, workspaces):
    r = Retargeter(talos, arms_down, workspaces=workspaces)
    refs = r.references_at(0.0)
    assert set(refs) == set(EFFECTORS) and all(isinstance(m, pin.SE3) for m in refs.values())
    for name, pose in refs.items():
        np.testing.assert_allclose(pose.rotation, r.reference_poses[name].rotation, atol=1e-9)
        np.testing.assert_allclose(pose.rotation.T @ pose.rotation, np.eye(3), atol=1e-12)


def test_head_turning_rotates_the_head_reference_about_the_vertical(talos, workspaces):
    rec = open_recording("head_turning")
    r = Retargeter(talos, rec, workspaces=workspaces)
    R0 = r.reference_poses["head"].rotation
    t_peak = 1.0 + 0.75  # yaw sine of period 3 s starting at 1 s: +60 deg at 1.75 s
    R = r.references_at(t_peak)["head"].rotation
    rotvec = pin.log3(R @ R0.T)  # world-axes rotation from the reference posture
    assert np.degrees(rotvec[2]) == pytest.approx(60.0, abs=1.0)
    assert np.linalg.norm(rotvec[:2]) < 1e-3
    np.testing.assert_allclose(r.references_at(t_peak)["head"].translation, r.references_at(0.0)["head"].translation,
                               atol=1e-6)  # the head point (upper neck) does not move when yawing


@pytest.mark.parametrize("angles", [True, False])
def test_references_do_not_depend_on_the_suit_world_frame(talos, arms_down, workspaces, angles):
    rec = open_recording("reach_forward")
    base = Retargeter(talos, rec, workspaces=workspaces)
    R = pin.rpy.rpyToMatrix(0.3, -1.2, 2.0)
    moved = Retargeter(talos, _moved(rec, R, np.array([3.0, -2.0, 0.5]), angles=angles), workspaces=workspaces,
                       human=HumanModel.from_recording(rec))
    assert moved.calibration.method == ("joint_angles" if angles else "fit")
    tol = 1e-6 if angles else 0.01  # a fitted posture differs from the exact one by millimetres
    for t in (0.0, 2.7, 7.3, 9.5):
        a, b = base.references_at(t), moved.references_at(t)
        for name in EFFECTORS:
            np.testing.assert_allclose(b[name].translation, a[name].translation, atol=tol)
            assert np.linalg.norm(pin.log3(b[name].rotation @ a[name].rotation.T)) < (1e-6 if angles else 0.02)


def test_validity_outside_the_recording(talos, arms_down, workspaces):
    r = Retargeter(talos, arms_down, workspaces=workspaces)
    assert r.valid_at(1.0)
    late = r.sample(arms_down.duration + 1.0)
    assert not late.valid
    last = r.sample(arms_down.duration)
    for name in EFFECTORS:
        np.testing.assert_allclose(late.references[name].translation, last.references[name].translation)
    assert not r.sample(-0.5).valid


def test_out_of_reach_targets_are_clamped_and_flagged(talos, workspaces):
    rec = open_recording("reach_sideways")
    r = Retargeter(talos, rec, workspaces=workspaces, proportion=1.6)  # a giant operator
    sample = r.sample(9.5)  # both arms stretched sideways
    for side in ("left_hand", "right_hand"):
        assert sample.clamped[side]
        shell = r.workspaces[side]
        d = np.linalg.norm(sample.references[side].translation - shell.center)
        assert d == pytest.approx(shell.r_max)
    assert sample.valid  # clamping does not invalidate
    at_rest = r.sample(0.0).clamped
    assert not at_rest["left_hand"] and not at_rest["right_hand"] and at_rest["head"]  # a giant's head is too high
    unclamped = Retargeter(talos, rec, workspaces={}, proportion=1.6).sample(9.5)
    assert not any(unclamped.clamped.values())


def test_workspaces_contain_the_reference_posture(talos, workspaces):
    data = talos.model.createData()
    pin.framesForwardKinematics(talos.model, data, talos.q0)
    frames = {"left_hand": talos.profile.hands[Side.LEFT], "right_hand": talos.profile.hands[Side.RIGHT],
              "head": talos.profile.head_frame}
    for name, frame in frames.items():
        p = data.oMf[talos.model.getFrameId(frame)].translation
        assert workspaces[name].contains(p), name
    assert workspaces["left_hand"].root_joint == "arm_left_1_joint"
    assert workspaces["head"].root_joint == "torso_1_joint"
    assert 0.6 < workspaces["left_hand"].r_max < 0.9


def test_proportions(talos, arms_down, workspaces):
    human = HumanModel.from_recording(arms_down)
    unit = Retargeter(talos, arms_down, workspaces=workspaces, proportion=1.0, human=human)
    head = Retargeter(talos, arms_down, workspaces=workspaces, proportion="head", human=human)
    assert unit.calibration.proportion == 1.0
    # "head": the operator's head point maps onto the robot's head frame height at calibration
    assert head.references_at(0.0)["head"].translation[2] == pytest.approx(
        head.reference_poses["head"].translation[2], abs=0.01)
    with pytest.raises(ConfigError, match="proportion"):
        Retargeter(talos, arms_down, workspaces=workspaces, proportion="knees")


def test_missing_segments_are_reported(talos, workspaces):
    rec = open_recording("arms_down")
    keep = [k for k, s in enumerate(rec.segments) if s != "LeftHand"]
    partial = MocapRecording(
        source="partial.bvh", frame_rate=rec.frame_rate, times=rec.times,
        segments=tuple(rec.segments[k] for k in keep), positions=rec.positions[:, keep],
        orientations=rec.orientations[:, keep],
    )
    with pytest.raises(ConfigError, match="partial.bvh.*LeftHand"):
        Retargeter(talos, partial, workspaces=workspaces, human=HumanModel())


def test_live_stream_end_to_end(talos, workspaces):
    """Replay a recording over loopback; the live retargeter calibrates on the first frame (positions only, so
    it fits the model) and ends on the same references as the offline one."""
    rec = open_recording("slow_circle")
    start, stop = 0, 60  # the first 1.2 s (standing still, then the arm starts to move)
    offline = Retargeter(talos, rec, workspaces=workspaces)
    with UdpPoseReceiver(stale_after=0.5) as receiver:
        live = Retargeter(talos, receiver, workspaces=workspaces, human=HumanModel.from_recording(rec))
        assert live.calibration is None
        waiting = live.sample(0.0)
        assert not waiting.valid  # no data yet: the robot's reference poses
        np.testing.assert_allclose(waiting.references["head"].translation, live.reference_poses["head"].translation)
        with ReplaySender(rec, receiver.port, speed=20.0) as sender:
            sender.run(start, stop)
        end = time.monotonic() + 2.0
        while receiver.stats.received < stop - start and time.monotonic() < end:
            receiver.poll()
            time.sleep(0.001)
        sample = live.sample(0.0)
        assert sample.valid and live.calibration is not None and live.calibration.method == "fit"
        assert receiver.latest.sequence == stop - 1
        expected = offline.references_at(rec.times[stop - 1])
        for name in EFFECTORS:
            np.testing.assert_allclose(sample.references[name].translation, expected[name].translation, atol=0.01)
        live_stale = Retargeter(talos, receiver, workspaces=workspaces, human=HumanModel.from_recording(rec))
        time.sleep(0.55)
        assert not live_stale.sample(0.0).valid  # stale stream: last frame held, flagged invalid


def test_calibrating_without_data_raises(talos, workspaces):
    with UdpPoseReceiver() as receiver:
        r = Retargeter(talos, receiver, workspaces=workspaces)
        with pytest.raises(WbcError, match="no frame"):
            r.calibrate()


def talos_left_gripper_repulsors():
    """The repulsors proposed for TALOS' left gripper (README, "Self-collision repulsors")."""
    return [
        RepulsionPoint("gripper_right_base_link", 0.10, (0.0, 0.0, -0.09), name="other_gripper"),
        RepulsionPoint("arm_right_5_link", 0.05, name="other_forearm"),
        RepulsionPoint("torso_2_link", 0.10, name="chest"),
        RepulsionPoint("base_link", 0.15, name="pelvis"),
        RepulsionPoint("base_link", 0.115, (0.0, 0.10, 0.0), name="pelvis_left"),
        RepulsionPoint("base_link", 0.115, (0.0, -0.10, 0.0), name="pelvis_right"),
        RepulsionPoint("leg_left_1_link", 0.15, name="hip_left"),
        RepulsionPoint("leg_right_1_link", 0.15, name="hip_right"),
        RepulsionPoint("leg_left_3_link", 0.12, (0.0, 0.10, -0.20), name="thigh_left"),
        RepulsionPoint("leg_right_3_link", 0.12, (0.0, -0.10, -0.20), name="thigh_right"),
        RepulsionPoint("leg_left_4_link", 0.10, name="knee_left"),
        RepulsionPoint("leg_right_4_link", 0.10, name="knee_right"),
    ]


def test_arms_down_targets_fall_in_the_proposed_talos_repulsors(talos, arms_down, workspaces):
    """Half-sitting leaves the proposed repulsors (nearly) idle; the arms-down hand targets are deep inside the
    hip and thigh ones: the situation of paper 004 Fig. 4."""
    model = talos.model
    data = model.createData()
    update_kinematics(model, data, talos.q0, np.zeros(model.nv))
    task = SelfCollisionTask(model, "gripper_left_base_link", talos_left_gripper_repulsors(), radius=0.10,
                             offset=(0.0, 0.0, -0.09), exponent=3.0, normalized=True, kp=500.0, weight=700.0)
    C0 = dict(zip(task.axis_names, task.values(model, data), strict=True))
    assert max(C0.values()) < 0.06 and not task.active(model, data).any()
    # the attractors at the gripper centre the arms-down targets ask for, the body in half-sitting
    r = Retargeter(talos, arms_down, workspaces=workspaces)
    repulsors = talos_left_gripper_repulsors()
    points = {}
    for name, rep in zip(task.axis_names, repulsors, strict=True):
        M = pin.updateFramePlacement(model, data, model.getFrameId(rep.frame))
        points[name] = M.translation + M.rotation @ np.array(rep.offset)
    peak = dict.fromkeys(task.axis_names, 0.0)
    for t in np.arange(0.0, arms_down.duration, 0.5):
        target = r.references_at(t)["left_hand"]
        centre = target.translation + target.rotation @ np.array([0.0, 0.0, -0.09])
        for name, s in zip(task.axis_names, task.scales, strict=True):
            peak[name] = max(peak[name], attractor(centre - points[name], 3.0, s)[0])
    assert peak["hip_left"] > 0.9 and peak["thigh_left"] > 0.6
    assert peak["other_gripper"] < 1e-6 and peak["chest"] < 1e-3


def test_a_squatting_operator_leans_the_head_target_instead_of_sinking_it(talos, workspaces, tmp_path):
    """An operator who squats and bends forward (a fixture of our own, written as BVH) puts his head below TALOS'
    torso after scaling; the radial clamp alone kept it there (and the head task crouched TALOS below its fall
    height on a public recording). The head's shell is also a cone: the target is turned onto it, above the
    torso joint, at the same distance."""
    from wbcbench.teleop import load_recording, write_bvh
    from wbcbench.teleop.synthetic import SyntheticMotion, _both, _keyframes, motion_configurations

    squat = _both({"right_hip_Z": 100.0, "right_knee_Z": 130.0, "right_ankle_Z": 40.0, "middle_lumbar_Z": 50.0,
                   "right_shoulder_Z": 40.0})
    motion = SyntheticMotion("deep_squat", "squat and bend forward", "A", 3.0, 50.0,
                             lambda t: _keyframes(t, [(0.5, {}), (2.5, squat)]))
    human, _, qs = motion_configurations(motion)
    path = write_bvh(tmp_path / "deep_squat.bvh", human.bvh_skeleton(0.01), human.bvh_motion(qs, 0.01), 1 / 50.0)
    rec = load_recording(path)
    head = workspaces["head"]
    assert np.degrees(head.max_tilt) < 90.0 and workspaces["left_hand"].max_tilt == pytest.approx(np.pi)
    radial = dict(workspaces, head=type(head)(head.center, head.r_min, head.r_max, head.root_joint))
    sunk = Retargeter(talos, rec, workspaces=radial).sample(3.0)
    assert sunk.references["head"].translation[2] < head.center[2]  # below the torso joint: the crouch
    sample = Retargeter(talos, rec, workspaces=workspaces).sample(3.0)
    p = sample.references["head"].translation
    assert sample.clamped["head"] and head.contains(p, tol=1e-9)
    delta = p - head.center
    assert np.arccos(delta[2] / np.linalg.norm(delta)) == pytest.approx(head.max_tilt)
    assert p[2] > head.center[2] + head.r_min * np.cos(head.max_tilt) - 1e-9
