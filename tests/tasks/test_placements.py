"""The compiled joint and frame placements (wbcbench/tasks/placements.py) against pinocchio's forward kinematics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.tasks.placements import ForwardKinematics


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_joint_and_frame_placements_are_pinocchios(erd_talos, seed):
    model = erd_talos.model
    data = model.createData()
    q, _ = erd_talos.random_state(seed)
    fk = ForwardKinematics(model)
    assert fk.supported
    R, t = fk.joints(q)
    pin.forwardKinematics(model, data, q)
    for j in range(model.njoints):
        np.testing.assert_allclose(R[j], data.oMi[j].rotation, atol=1e-12, err_msg=str(j))
        np.testing.assert_allclose(t[j], data.oMi[j].translation, atol=1e-12, err_msg=str(j))
    ids = [model.getFrameId(n) for n in ("left_sole_link", "right_sole_link", "head_1_link", "gripper_left_base_link")]
    Rf, tf = np.empty((4, 3, 3)), np.empty((4, 3))
    fk.frames(q, fk.frame_arrays(ids), Rf, tf)
    for k, i in enumerate(ids):
        M = pin.updateFramePlacement(model, data, i)
        np.testing.assert_allclose(Rf[k], M.rotation, atol=1e-12)
        np.testing.assert_allclose(tf[k], M.translation, atol=1e-12)


def test_other_joint_types_are_not_supported():
    model = pin.Model()
    j = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "hinge")
    assert ForwardKinematics(model).supported
    model.addJoint(j, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    assert not ForwardKinematics(model).supported


def test_a_subset_of_joints(erd_talos):
    model = erd_talos.model
    q, _ = erd_talos.random_state(4)
    fk = ForwardKinematics(model)
    R_all, t_all = (x.copy() for x in fk.joints(q))
    joints = np.array([5, 1, 22, 0], dtype=np.intp)
    R, t = fk.joints(q, joints, np.empty((4, 3, 3)), np.empty((4, 3)))
    np.testing.assert_array_equal(R, R_all[joints])
    np.testing.assert_array_equal(t, t_all[joints])
