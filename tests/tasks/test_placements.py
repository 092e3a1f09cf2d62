"""The compiled joint and frame placements (wbcbench/tasks/placements.py) against pinocchio's forward kinematics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.tasks.placements import CenterOfMass, ForwardKinematics


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


@pytest.mark.parametrize("seed", [0, 1])
def test_pruned_kinematics_give_the_kept_joints_and_frames_bit_for_bit(erd_talos, seed):
    """A foot's placement from its leg alone (`pruned`: the frame batch's and estimators' use) is the whole model's,
    the same bits; the arms and head are not computed at all."""
    model = erd_talos.model
    q, _ = erd_talos.random_state(seed)
    fk = ForwardKinematics(model)
    ids = [model.getFrameId(n) for n in ("left_sole_link", "right_sole_link")]
    legs = fk.pruned([model.frames[i].parentJoint for i in ids])
    kept = sorted(legs._index, key=legs._index.get)
    assert kept[0] == 0 and len(kept) == 14 and len(kept) < model.njoints  # universe, free flyer, 2 x 6 leg joints
    assert all(model.names[j].startswith(("root", "leg_", "universe")) for j in kept)
    R, t = fk.joints(q)
    R_sub, t_sub = legs.joints(q)
    assert np.array_equal(R_sub, R[kept]) and np.array_equal(t_sub, t[kept])
    Rf, tf = np.empty((2, 3, 3)), np.empty((2, 3))
    Rf_sub, tf_sub = np.empty((2, 3, 3)), np.empty((2, 3))
    fk.frames(q, fk.frame_arrays(ids), Rf, tf)
    legs.frames(q, legs.frame_arrays(ids), Rf_sub, tf_sub)
    assert np.array_equal(Rf_sub, Rf) and np.array_equal(tf_sub, tf)


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


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_center_of_mass_and_its_velocity_are_pinocchios(erd_talos, seed):
    """The compiled CoM and CoM velocity (the log's ground truth) equal pinocchio's centerOfMass(q, v) to
    rounding, one row and a block of rows (random states: base anywhere, every joint moving)."""
    model = erd_talos.model
    data = model.createData()
    com = CenterOfMass(model)
    assert com.supported
    rng = np.random.default_rng(seed)
    nq, nv = model.nq, model.nv
    rows = np.full((5, 3 + nq + nv + 6 + 2), np.nan)  # columns: padding, q, v, com, com_vel, padding
    for r in range(5):
        q, _ = erd_talos.random_state(seed * 10 + r)
        rows[r, 3:3 + nq] = q
        rows[r, 3 + nq:3 + nq + nv] = rng.normal(scale=2.0, size=nv)
    one = rows[0].copy()
    com.write(one, 3, 3 + nq, 3 + nq + nv)
    com.write_rows(rows, 3, 3 + nq, 3 + nq + nv)
    np.testing.assert_array_equal(one, rows[0])
    for r in range(5):
        pin.centerOfMass(model, data, rows[r, 3:3 + nq], rows[r, 3 + nq:3 + nq + nv], False)
        out = rows[r, 3 + nq + nv:3 + nq + nv + 6]
        np.testing.assert_allclose(out[:3], data.com[0], rtol=0, atol=1e-13)
        np.testing.assert_allclose(out[3:], data.vcom[0], rtol=0, atol=1e-12)
    assert np.isnan(rows[:, :3]).all() and np.isnan(rows[:, -2:]).all()  # nothing written outside
