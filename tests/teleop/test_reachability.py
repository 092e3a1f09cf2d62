"""Reachability of an effector's reference by its own chain (wbcbench/teleop/human/reachability.py): poses the arm
can take are found from another start, poses beyond the arm are not, and the speed-limited follower reaches a
pose in the time its joints' velocity limits allow, not sooner."""

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


def test_the_follower_reaches_a_pose_in_the_time_its_joints_need(talos, left_arm):
    """A pose 0.6 rad away on every arm joint: with dt shorter than the slowest joint needs, the follower is not
    there and no joint moved more than its limit allows; given the time, it is."""
    check, frame = left_arm
    q = talos.q0.copy()
    x0 = q[check.q_index].copy()
    delta = np.where(x0 + 0.6 <= check.upper, 0.6, -0.6)
    q[check.q_index] = x0 + delta
    data, M = _placements(talos, q, frame)
    parent = data.oMi[check.parent]  # (the torso does not move: the arm's parent is the same at q0)
    need = float(np.max(np.abs(delta) / check.velocity_limit))  # the slowest joint's time at its limit
    short = check.track(x0, 0.5 * need, parent, M)
    assert not short.reachable and short.position_residual > 0.02
    assert np.all(np.abs(short.q - x0) <= check.velocity_limit * 0.5 * need + 1e-12)
    x, t = x0, 0.0
    while t < 3.0 * need:  # sampled every 10 ms, as the metrics do
        res = check.track(x, 0.01, parent, M)
        x, t = res.q, t + 0.01
        if res.reachable:
            break
    assert res.reachable and 0.5 * need < t <= 1.5 * need
    assert res.position_residual <= check.position_tolerance and res.rotation_residual <= check.rotation_tolerance
    with pytest.raises(ValueError, match="dt"):
        check.track(x0, -0.01, parent, M)
