"""PostureTask: actuated joints only, Lie-group error, joint subsets by name, per-joint gains."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.tasks import PostureTask, TaskConfigError, UnknownNameError, acceleration_rows, velocity_rows

SEEDS = st.integers(min_value=0, max_value=2**31 - 1)


def test_default_selects_every_actuated_joint(erd_talos):
    model = erd_talos.model
    task = PostureTask(model, kp=1.0)
    assert task.dim == model.nv - 6 == 32
    assert "root_joint" not in task.joint_names
    np.testing.assert_array_equal(task.velocity_indices, np.arange(6, model.nv))
    data = erd_talos.at(model.createData(), erd_talos.q0)
    J = task.jacobian(model, data)
    np.testing.assert_array_equal(J, np.hstack([np.zeros((32, 6)), np.eye(32)]))


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_error_jacobian_velocity_and_drift(erd_talos, seed):
    model = erd_talos.model
    data = model.createData()
    q, v = erd_talos.random_state(seed)
    q_ref, _ = erd_talos.random_state(seed + 1)
    task = PostureTask(model, kp=1.0)
    task.set_reference(q_ref)
    erd_talos.at(data, q, v)
    np.testing.assert_allclose(task.error(model, data), (q_ref - q)[7:], atol=1e-12)  # revolute joints
    np.testing.assert_allclose(task.velocity(model, data), v[6:])
    np.testing.assert_array_equal(task.drift(model, data), 0.0)
    de_fd = erd_talos.numerical_jacobian(q, lambda qq: task.error(model, erd_talos.at(data, qq)))
    np.testing.assert_allclose(de_fd, -task.jacobian(model, data), atol=1e-8)


def test_subset_by_name_in_the_given_order_with_mapping_gains(erd_talos):
    model = erd_talos.model
    joints = ["torso_2_joint", "leg_left_4_joint", "head_1_joint"]
    task = PostureTask(
        model, joints=joints, kp={"leg_left_4_joint": 5.0, "torso_2_joint": 100.0, "head_1_joint": 1.0}, kd=2.0
    )
    assert task.joint_names == tuple(joints)
    assert task.axis_names == tuple(joints)
    np.testing.assert_array_equal(task.kp, [100.0, 5.0, 1.0])
    idx = [model.joints[model.getJointId(j)].idx_v for j in joints]
    np.testing.assert_array_equal(task.velocity_indices, idx)

    q, v = erd_talos.random_state(2)
    data = erd_talos.at(model.createData(), q, v)
    q_ref = erd_talos.q0.copy()
    q_ref[:7] = np.nan  # every entry must be finite ...
    with pytest.raises(TaskConfigError, match="q_ref"):
        task.set_reference(q_ref)
    q_ref[:7] = 0.0  # ... but unselected joints are otherwise ignored: a zero quaternion is fine
    task.set_reference(q_ref, velocity=[1.0, 2.0, 3.0])
    A, b = acceleration_rows(task, model, data)
    np.testing.assert_array_equal(A, np.eye(model.nv)[idx])
    iq = [model.joints[model.getJointId(j)].idx_q for j in joints]
    expected = 2.0 * (np.array([1.0, 2.0, 3.0]) - v[idx]) + task.kp * (erd_talos.q0[iq] - q[iq])
    np.testing.assert_allclose(b, expected, atol=1e-12)
    np.testing.assert_allclose(
        velocity_rows(task, model, data).b, [1.0, 2.0, 3.0] + task.kp * (erd_talos.q0[iq] - q[iq])
    )


def test_masked_rows_and_rest(erd_talos):
    model = erd_talos.model
    data = erd_talos.at(model.createData(), erd_talos.q0, np.zeros(model.nv))
    mask = np.zeros(32, dtype=bool)
    mask[[0, 5, 31]] = True
    task = PostureTask(model, kp=10.0, mask=mask)
    task.set_reference_to_current(model, data)
    A, b = acceleration_rows(task, model, data)
    np.testing.assert_array_equal(A, np.eye(model.nv)[[6, 11, 37]])
    np.testing.assert_allclose(b, 0.0, atol=1e-15)


def test_bad_joint_names_and_gains(erd_talos):
    model = erd_talos.model
    with pytest.raises(UnknownNameError) as info:
        PostureTask(model, kp=1.0, joints=["leg_left_4_jiont"])
    assert "leg_left_4_joint" in str(info.value)
    with pytest.raises(TaskConfigError, match="floating root"):
        PostureTask(model, kp=1.0, joints=["root_joint"])
    with pytest.raises(TaskConfigError, match="twice"):
        PostureTask(model, kp=1.0, joints=["head_1_joint", "head_1_joint"])
    with pytest.raises(TaskConfigError, match="string"):
        PostureTask(model, kp=1.0, joints="head_1_joint")
    with pytest.raises(TaskConfigError, match="missing"):
        PostureTask(model, kp={"head_1_joint": 1.0}, joints=["head_1_joint", "head_2_joint"])
    with pytest.raises(TaskConfigError, match="kp"):
        PostureTask(model, kp={"head_1_joint": -1.0}, joints=["head_1_joint"])
    with pytest.raises(TaskConfigError, match="kp"):
        PostureTask(model, kp=np.ones(31))
    task = PostureTask(model, kp=1.0)
    with pytest.raises(TaskConfigError, match="q_ref"):
        task.set_reference(np.zeros(model.nq - 1))
    with pytest.raises(TaskConfigError, match="velocity"):
        task.set_reference(erd_talos.q0, velocity=np.zeros(model.nv))


def test_continuous_joint_uses_the_lie_group_difference():
    """A non-TALOS model: a continuous (unbounded revolute, nq 2, nv 1) joint after a free-flyer."""
    model = pin.Model()
    ff = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "root")
    wheel = model.addJoint(ff, pin.JointModelRUBZ(), pin.SE3.Identity(), "wheel")
    for j in (ff, wheel):
        model.appendBodyToJoint(j, pin.Inertia.Random(), pin.SE3.Identity())
    data = model.createData()
    task = PostureTask(model, kp=1.0)
    assert task.joint_names == ("wheel",)
    q = pin.neutral(model)
    q_ref = q.copy()
    q[7:] = [np.cos(3.0), np.sin(3.0)]
    q_ref[7:] = [np.cos(-3.0), np.sin(-3.0)]
    task.set_reference(q_ref)
    from wbcbench.tasks import update_kinematics_velocity_level

    update_kinematics_velocity_level(model, data, q)
    np.testing.assert_allclose(task.error(model, data), [2 * np.pi - 6.0], atol=1e-12)  # the short way round
