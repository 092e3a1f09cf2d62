"""Reachability of an effector's reference by its own chain (wbcbench/teleop/human/reachability.py): poses the arm
can take are found from another start, poses beyond the arm are not, and the speed ratio scales with the
reference's speed."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.side import Side
from wbcbench.teleop.human.reachability import ChainReach
from wbcbench.teleop.human.workspace import chain_joints


@pytest.fixture(scope="module")
def left_arm(talos):
    model = talos.model
    torso = model.frames[model.getFrameId(talos.profile.torso_frame)].parentJoint
    frame = talos.profile.hands[Side.LEFT]
    return ChainReach(model, frame, chain_joints(model, frame, torso), talos.q0), frame


def _placements(talos, q, frame):
    data = talos.model.createData()
    pin.framesForwardKinematics(talos.model, data, q)
    return data, data.oMf[talos.model.getFrameId(frame)].copy()


def test_a_pose_the_arm_takes_is_found_reachable_from_elsewhere(talos, left_arm):
    check, frame = left_arm
    rng = np.random.default_rng(3)
    found = 0
    for _ in range(8):
        q = talos.q0.copy()
        q[check.q_index] = rng.uniform(check.lower, check.upper)
        data, M = _placements(talos, q, frame)
        check._last = None
        # the robot is at its reference posture: the search starts there, not at the pose's joints
        res = check.solve(talos.q0, data.oMi[check.parent], M)
        found += res.reachable
        if res.reachable:
            assert res.position_residual <= check.position_tolerance
            assert res.rotation_residual <= check.rotation_tolerance
    assert found >= 7  # a local minimum may miss one


def test_the_reference_follows_the_chains_parent(talos, left_arm):
    """With the torso turned 0.5 rad, the hand's pose is reachable from the turned torso, and not from the
    upright one (the same world pose, 0.5 rad of torso yaw away from anything the arm alone can do)."""
    check, frame = left_arm
    q = talos.q0.copy()
    q[talos.model.joints[talos.model.getJointId("torso_1_joint")].idx_q] = 0.5
    data, M = _placements(talos, q, frame)
    check._last = None
    assert check.solve(q, data.oMi[check.parent], M).reachable
    data0, _ = _placements(talos, talos.q0, frame)
    check._last = None
    assert not check.solve(talos.q0, data0.oMi[check.parent], M).reachable


def test_beyond_the_arm_is_out_of_reach(talos, left_arm):
    check, frame = left_arm
    data, M = _placements(talos, talos.q0, frame)
    shoulder = data.oMi[talos.model.getJointId("arm_left_2_joint")].translation
    far = pin.SE3(M.rotation, shoulder + np.array([0.3, 0.4, -0.75]))  # 0.9 m from the shoulder
    check._last = None
    res = check.solve(talos.q0, data.oMi[check.parent], far)
    assert not res.reachable and res.position_residual > 0.05


def test_speed_ratio_scales_with_the_reference_speed(talos, left_arm):
    check, frame = left_arm
    data, M = _placements(talos, talos.q0, frame)
    check._last = None
    res = check.solve(talos.q0, data.oMi[check.parent], M)
    v, w = np.array([0.3, 0.1, -0.2]), np.array([0.0, 0.5, 0.2])
    r1 = check.speed_ratio(res.q, data.oMi[check.parent], v, w)
    assert r1 > 0
    assert check.speed_ratio(res.q, data.oMi[check.parent], 4 * v, 4 * w) == pytest.approx(4 * r1, rel=1e-9)
    assert check.speed_ratio(res.q, data.oMi[check.parent], 0 * v, 0 * w) == 0.0
    # a hand at 3 m/s is beyond what TALOS' arm joints (1.8 to 4.6 rad/s) can do
    assert check.speed_ratio(res.q, data.oMi[check.parent], np.array([3.0, 0.0, 0.0]), np.zeros(3)) > 1.0
