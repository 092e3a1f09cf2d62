"""FrameTask: Jacobian, error, drift against finite differences; masks; references; validation."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.tasks import (
    FrameTask,
    ReferenceNotSetError,
    TaskConfigError,
    UnknownNameError,
    acceleration_rows,
    velocity_rows,
)

SEEDS = st.integers(min_value=0, max_value=2**31 - 1)
FRAMES = st.sampled_from(["left_sole_link", "torso_2_link", "gripper_left_base_link", "base_link"])


def _pose(model, data, frame_id):
    return pin.SE3(pin.updateFramePlacement(model, data, frame_id))


@settings(max_examples=12, deadline=None)
@given(seed=SEEDS, frame=FRAMES)
def test_jacobian_matches_finite_differences_of_the_placement(erd_talos, seed, frame):
    model = erd_talos.model
    data = model.createData()
    task = FrameTask(model, frame, kp=1.0)
    q, _ = erd_talos.random_state(seed)
    erd_talos.at(data, q)
    M0 = _pose(model, data, task.frame_id)

    def displacement(qq):  # [p - p0; log3(R R0^T)]: world-axes linear and angular displacement
        M = _pose(model, erd_talos.at(data, qq), task.frame_id)
        return np.concatenate([M.translation - M0.translation, pin.log3(M.rotation @ M0.rotation.T)])

    J_fd = erd_talos.numerical_jacobian(q, displacement)
    J = task.jacobian(model, erd_talos.at(data, q))
    np.testing.assert_allclose(J, J_fd, atol=1e-6)


@settings(max_examples=12, deadline=None)
@given(seed=SEEDS, frame=FRAMES)
def test_error_derivative_matches_jacobian(erd_talos, seed, frame):
    """d e/dq = -[J_lin; Jlog3(R_ref R^T) J_ang] for any reference, -J at the reference."""
    model = erd_talos.model
    data = model.createData()
    task = FrameTask(model, frame, kp=1.0)
    q, _ = erd_talos.random_state(seed)
    q_ref, _ = erd_talos.random_state(seed + 1)
    erd_talos.at(data, q_ref)
    task.set_reference_to_current(model, data)
    erd_talos.at(data, q)

    de_fd = erd_talos.numerical_jacobian(q, lambda qq: task.error(model, erd_talos.at(data, qq)))
    erd_talos.at(data, q)
    J = task.jacobian(model, data)
    R = _pose(model, data, task.frame_id).rotation
    expected = -np.vstack([J[:3], pin.Jlog3(task.reference.rotation @ R.T) @ J[3:]])
    np.testing.assert_allclose(de_fd, expected, atol=1e-5)

    task.set_reference_to_current(model, data)
    np.testing.assert_allclose(task.error(model, data), 0.0, atol=1e-12)
    de_fd = erd_talos.numerical_jacobian(q, lambda qq: task.error(model, erd_talos.at(data, qq)))
    np.testing.assert_allclose(de_fd, -J, atol=1e-6)


@settings(max_examples=12, deadline=None)
@given(seed=SEEDS, frame=FRAMES)
def test_drift_and_velocity_match_finite_differences(erd_talos, seed, frame):
    model = erd_talos.model
    data = model.createData()
    task = FrameTask(model, frame, kp=1.0)
    q, v = erd_talos.random_state(seed)
    erd_talos.at(data, q, v)
    velocity, drift = task.velocity(model, data), task.drift(model, data)
    np.testing.assert_allclose(velocity, task.jacobian(model, data) @ v, atol=1e-10)
    drift_fd = erd_talos.along(q, v, lambda qq: task.jacobian(model, erd_talos.at(data, qq)) @ v)
    np.testing.assert_allclose(drift, drift_fd, atol=1e-5 * (1 + np.abs(drift_fd).max()))


def test_error_is_reference_minus_current_in_world_axes(erd_talos):
    model, q = erd_talos.model, erd_talos.q0
    data = erd_talos.at(erd_talos.model.createData(), q)
    task = FrameTask(model, "gripper_left_base_link", kp=1.0)
    M = _pose(model, data, task.frame_id)
    offset = np.array([0.1, -0.2, 0.05])
    rot = pin.exp3(np.array([0.0, 0.0, 0.3]))  # 0.3 rad about world z
    task.set_reference(pin.SE3(rot @ M.rotation, M.translation + offset))
    np.testing.assert_allclose(task.error(model, data), np.r_[offset, 0.0, 0.0, 0.3], atol=1e-12)


def test_masked_rows_are_exactly_the_selected_axes(erd_talos):
    model = erd_talos.model
    q, v = erd_talos.random_state(3)
    data = erd_talos.at(model.createData(), q, v)
    full = FrameTask(model, "torso_2_link", kp=[1, 2, 3, 4, 5, 6], kd=[6, 5, 4, 3, 2, 1])
    full.set_reference(pin.SE3(pin.exp3(np.array([0.1, 0.2, 0.3])), np.array([0.1, 0.2, 1.0])))
    A, b = acceleration_rows(full, model, data)
    Av, bv = velocity_rows(full, model, data)
    for mask in ([0, 0, 0, 1, 1, 1], [1, 0, 1, 0, 1, 0], [True, True, False, False, False, True]):
        task = FrameTask(model, "torso_2_link", kp=full.kp, kd=full.kd, mask=mask)
        task.set_reference(full.reference)
        rows = np.flatnonzero(mask)
        A_m, b_m = acceleration_rows(task, model, data)
        np.testing.assert_array_equal(A_m, A[rows])
        np.testing.assert_array_equal(b_m, b[rows])
        Av_m, bv_m = velocity_rows(task, model, data)
        np.testing.assert_array_equal(Av_m, Av[rows])
        np.testing.assert_array_equal(bv_m, bv[rows])


def test_rows_follow_the_control_laws(erd_talos):
    model = erd_talos.model
    q, v = erd_talos.random_state(5)
    data = erd_talos.at(model.createData(), q, v)
    task = FrameTask(model, "left_sole_link", kp=[10, 20, 30, 40, 50, 60], kd=3.0)
    v_ref, a_ref = np.arange(6.0), -np.arange(6.0)
    task.set_reference(pin.SE3.Identity(), v_ref, a_ref)
    J, e = task.jacobian(model, data), task.error(model, data)
    A, b = acceleration_rows(task, model, data)
    np.testing.assert_array_equal(A, J)
    expected = a_ref + 3.0 * (v_ref - J @ v) + task.kp * e - task.drift(model, data)
    np.testing.assert_allclose(b, expected, atol=1e-10)
    A, b = velocity_rows(task, model, data)
    np.testing.assert_allclose(b, v_ref + task.kp * e, atol=1e-12)


def test_rows_vanish_at_rest_on_the_reference(erd_talos):
    model = erd_talos.model
    q, _ = erd_talos.random_state(11)
    data = erd_talos.at(model.createData(), q, np.zeros(model.nv))
    task = FrameTask(model, "torso_2_link", kp=100.0, kd=20.0, mask=[0, 0, 0, 1, 1, 1])
    task.set_reference_to_current(model, data)
    np.testing.assert_allclose(acceleration_rows(task, model, data).b, 0.0, atol=1e-12)
    np.testing.assert_allclose(velocity_rows(task, model, data).b, 0.0, atol=1e-12)


def test_default_kd_is_critical_damping(erd_talos):
    task = FrameTask(erd_talos.model, "base_link", kp=[100, 100, 100, 4, 4, 4])
    np.testing.assert_allclose(task.kd, [20, 20, 20, 4, 4, 4])


def test_unknown_frame_suggests_close_names(erd_talos):
    with pytest.raises(UnknownNameError) as info:
        FrameTask(erd_talos.model, "torso_2_lnk", kp=1.0, name="waist")
    message = str(info.value)
    assert "'torso_2_lnk'" in message and "'torso_2_link'" in message and "waist" in message
    assert isinstance(info.value, ValueError)
    assert info.value.suggestions[0] == "torso_2_link"


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"kp": -1.0}, "kp"),
        ({"kp": [1, 2, 3]}, "kp"),
        ({"kp": 1.0, "kd": [1, 1, 1, 1, 1, -1]}, "kd"),
        ({"kp": float("nan")}, "kp"),
        ({"kp": 1.0, "mask": [1, 1, 1]}, "mask"),
        ({"kp": 1.0, "mask": "000111"}, "mask"),
        ({"kp": 1.0, "mask": [0, 0, 0, 0, 0, 0]}, "mask"),
        ({"kp": 1.0, "mask": [0, 0, 0, 2, 1, 1]}, "mask"),
        ({"kp": 1.0, "weight": -1.0}, "weight"),
        ({"kp": 1.0, "weight": "heavy"}, "weight"),
        ({"kp": 1.0, "name": ""}, "name"),
    ],
)
def test_bad_construction_arguments_raise_clear_errors(erd_talos, kwargs, key):
    with pytest.raises(TaskConfigError) as info:
        FrameTask(erd_talos.model, "base_link", **kwargs)
    assert info.value.key == key
    assert "FrameTask" in str(info.value)


def test_setters_validate_and_references_are_checked(erd_talos):
    model = erd_talos.model
    data = erd_talos.at(model.createData(), erd_talos.q0)
    task = FrameTask(model, "base_link", kp=1.0)
    with pytest.raises(ReferenceNotSetError):
        task.error(model, data)
    with pytest.raises(TaskConfigError):
        task.kp = [-1, 0, 0, 0, 0, 0]
    with pytest.raises(TaskConfigError):
        task.weight = float("inf")
    with pytest.raises(TaskConfigError):
        task.set_reference(np.eye(4))
    with pytest.raises(TaskConfigError):
        task.set_reference(pin.SE3.Identity(), velocity=np.zeros(5))
    with pytest.raises(TaskConfigError):
        task.set_reference(pin.SE3(2.0 * np.eye(3), np.zeros(3)))
    task.set_reference(pin.SE3.Identity(), velocity=np.ones(6))
    np.testing.assert_array_equal(task.v_ref, np.ones(6))
    with pytest.raises(ValueError):
        task.kp[0] = 3.0  # read-only views
