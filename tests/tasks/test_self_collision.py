"""SelfCollisionTask (paper 004 Eq. 8-13): attractor derivatives, Jacobian and drift against finite differences,
rows equal to Eq. 12, repulsion behaviour, validation."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.tasks import (
    RepulsionPoint,
    SelfCollisionTask,
    TaskConfigError,
    UnknownNameError,
    acceleration_rows,
    velocity_rows,
)
from wbcbench.tasks.self_collision import attractor

SEEDS = st.integers(min_value=0, max_value=2**31 - 1)

#: Repulsors for the left gripper: moving bodies with offsets, and one point fixed in the world.
REPULSORS = (
    RepulsionPoint("base_link", 0.15, (0.0, 0.1, 0.0), name="hip_left"),
    RepulsionPoint("leg_left_3_link", 0.15, (0.0, 0.1, -0.2)),
    RepulsionPoint("torso_2_link", 0.10),
    RepulsionPoint("gripper_right_base_link", 0.10, (0.0, 0.0, -0.09)),
    RepulsionPoint("universe", 0.20, (0.3, 0.3, 0.8), name="fixed"),
)


def _task(model, **kwargs):
    options = dict(radius=0.25, offset=(0.0, 0.0, -0.09), kp=500.0, exponent=3.0, negligible=0.0)
    options.update(kwargs)
    return SelfCollisionTask(model, "gripper_left_base_link", REPULSORS, **options)


# ---------------------------------------------------------------------------------------------- attractor
@settings(max_examples=60, deadline=None)
@given(
    r=st.lists(st.floats(-0.6, 0.6), min_size=3, max_size=3),
    p=st.floats(2.0, 4.0),
    s=st.floats(0.02, 0.5),
)
def test_attractor_gradient_and_hessian_match_finite_differences(r, p, s):
    r = np.array(r)
    if np.linalg.norm(r) < 1e-3:
        r = r + 0.01
    C, g, H = attractor(r, p, s)
    assert C == pytest.approx(math.exp(-np.linalg.norm(r) ** p / s))
    h = 1e-6
    eye = np.eye(3)
    g_fd = np.array([(attractor(r + h * e, p, s)[0] - attractor(r - h * e, p, s)[0]) / (2 * h) for e in eye])
    H_fd = np.array([(attractor(r + h * e, p, s)[1] - attractor(r - h * e, p, s)[1]) / (2 * h) for e in eye])
    np.testing.assert_allclose(g, g_fd, atol=1e-7 * (1 + np.abs(g_fd).max()))
    np.testing.assert_allclose(H, H_fd, atol=1e-5 * (1 + np.abs(H_fd).max()))
    np.testing.assert_allclose(H, H.T, atol=1e-12)


@pytest.mark.parametrize("p", [2.0, 3.0])
def test_attractor_at_the_repulsion_point(p):
    C, g, H = attractor(np.zeros(3), p, 0.3)
    assert C == 1.0
    np.testing.assert_array_equal(g, 0.0)
    expected = -(2.0 / 0.3) * np.eye(3) if p == 2.0 else np.zeros((3, 3))
    np.testing.assert_allclose(H, expected)
    # and the Hessian is continuous there
    _, _, H_near = attractor(np.array([1e-7, 0.0, 0.0]), p, 0.3)
    np.testing.assert_allclose(H_near, expected, atol=1e-5)


def test_gradient_points_to_the_repulsor_so_the_dynamics_push_away():
    r = np.array([0.1, -0.05, 0.02])  # point minus repulsor
    _, g, _ = attractor(r, 3.0, 0.25)
    assert g @ r < 0.0  # C decreases when moving away from the repulsor


# ------------------------------------------------------------------------------------------------ the task
@settings(max_examples=8, deadline=None)
@given(seed=SEEDS, normalized=st.booleans())
def test_jacobian_matches_finite_differences_of_C(erd_talos, seed, normalized):
    model = erd_talos.model
    data = model.createData()
    task = _task(model, normalized=normalized, radius=0.25 if not normalized else 0.45)
    q, _ = erd_talos.random_state(seed)
    J_fd = erd_talos.numerical_jacobian(q, lambda qq: task.values(model, erd_talos.at(data, qq)))
    J = task.jacobian(model, erd_talos.at(data, q))
    np.testing.assert_allclose(J, J_fd, atol=1e-6 * (1 + np.abs(J_fd).max()))
    np.testing.assert_allclose(task.error(model, data), -task.values(model, data))


@settings(max_examples=8, deadline=None)
@given(seed=SEEDS, normalized=st.booleans())
def test_velocity_and_drift_match_finite_differences(erd_talos, seed, normalized):
    model = erd_talos.model
    data = model.createData()
    task = _task(model, normalized=normalized, radius=0.25 if not normalized else 0.45)
    q, v = erd_talos.random_state(seed)
    erd_talos.at(data, q, v)
    velocity, drift = task.velocity(model, data), task.drift(model, data)
    np.testing.assert_allclose(velocity, task.jacobian(model, data) @ v, atol=1e-12)
    # C_dot along q(t) = q (+) t v
    C_dot_fd = erd_talos.along(q, v, lambda qq: task.values(model, erd_talos.at(data, qq)))
    np.testing.assert_allclose(velocity, C_dot_fd, atol=1e-6 * (1 + np.abs(C_dot_fd).max()))
    # drift = d/dt (J v) at constant v = C_ddot at zero joint acceleration
    drift_fd = erd_talos.along(q, v, lambda qq: task.jacobian(model, erd_talos.at(data, qq)) @ v)
    np.testing.assert_allclose(drift, drift_fd, atol=1e-5 * (1 + np.abs(drift_fd).max()))


def test_acceleration_rows_are_eq_12(erd_talos):
    """A = grad C^T J, b = -((H J v)^T J v + grad C^T (J_dot v) + Kd J v + Kp C) per repulsor."""
    model = erd_talos.model
    q, v = erd_talos.random_state(7)
    data = erd_talos.at(model.createData(), q, v)
    task = _task(model, kp=[500.0, 400.0, 300.0, 200.0, 100.0], kd=3.0)
    A, b = acceleration_rows(task, model, data)
    np.testing.assert_array_equal(A, task.jacobian(model, data))
    C, C_dot = task.values(model, data), task.velocity(model, data)
    expected = -(task.drift(model, data) + 3.0 * C_dot + task.kp * C)
    np.testing.assert_allclose(b, expected, atol=1e-12)
    A_v, b_v = velocity_rows(task, model, data)
    np.testing.assert_allclose(b_v, -task.kp * C, atol=1e-12)


@pytest.mark.parametrize("seed", [3, 11])
def test_negligible_repulsors_get_zero_rows_and_the_others_exact_ones(erd_talos, seed):
    model = erd_talos.model
    q, v = erd_talos.random_state(seed)
    data = erd_talos.at(model.createData(), q, v)
    exact = _task(model, normalized=True, radius=0.3)
    C = exact.values(model, data)
    cut = float(np.sort(C)[len(C) // 2])  # about half the repulsors below the cut
    fast = _task(model, normalized=True, radius=0.3, negligible=cut)
    kept = C > cut
    assert 0 < kept.sum() < len(C)
    np.testing.assert_array_equal(fast.values(model, data), C)
    for name in ("jacobian", "drift"):
        a, b = getattr(fast, name)(model, data), getattr(exact, name)(model, data)
        np.testing.assert_allclose(a[kept], b[kept], rtol=1e-12, atol=1e-14)
        assert not a[~kept].any()
    A, b = acceleration_rows(fast, model, data)
    np.testing.assert_allclose(b[~kept], -(np.broadcast_to(fast.kp, C.shape) * C)[~kept])  # no velocity, no drift


def test_mask_selects_repulsors(erd_talos):
    model = erd_talos.model
    q, v = erd_talos.random_state(3)
    data = erd_talos.at(model.createData(), q, v)
    full = _task(model)
    A, b = acceleration_rows(full, model, data)
    part = _task(model, mask=[1, 0, 1, 0, 0])
    A_m, b_m = acceleration_rows(part, model, data)
    np.testing.assert_allclose(A_m, A[[0, 2]])
    np.testing.assert_allclose(b_m, b[[0, 2]])
    assert full.axis_names == ("hip_left", "leg_left_3_link", "torso_2_link", "gripper_right_base_link", "fixed")


def test_a_velocity_step_from_the_rows_moves_the_gripper_away(erd_talos):
    """Least-squares velocity from the rows only (J v = -Kp C) increases every active distance."""
    model = erd_talos.model
    q = erd_talos.q0.copy()
    data = model.createData()
    task = SelfCollisionTask(
        model, "gripper_left_base_link", [RepulsionPoint("universe", 0.2, name="near")], radius=0.1, kp=10.0,
        normalized=True,
    )
    # put the repulsion point 10 cm from the gripper: rebuild the task with that world point
    erd_talos.at(data, q)
    gripper = pin.updateFramePlacement(model, data, model.getFrameId("gripper_left_base_link")).translation
    point = tuple(gripper + np.array([0.0, -0.1, 0.0]))
    task = SelfCollisionTask(
        model, "gripper_left_base_link", [RepulsionPoint("universe", 0.2, point, name="near")], radius=0.1,
        kp=10.0, normalized=True,
    )
    d0 = task.distances(model, erd_talos.at(data, q))[0]
    assert task.active(model, data)[0] and d0 == pytest.approx(0.1)
    A, b = velocity_rows(task, model, data)
    v = np.linalg.lstsq(A, b, rcond=None)[0]
    q1 = pin.integrate(model, q, 0.01 * v)
    d1 = task.distances(model, erd_talos.at(data, q1))[0]
    assert d1 > d0
    moved = pin.updateFramePlacement(model, data, model.getFrameId("gripper_left_base_link")).translation - gripper
    assert moved[1] > 0.0  # away from the point, which lies on the -y side


def test_normalized_form_has_value_one_over_e_at_the_influence_radius(erd_talos):
    model = erd_talos.model
    data = erd_talos.at(model.createData(), erd_talos.q0)
    gripper = pin.updateFramePlacement(model, data, model.getFrameId("gripper_left_base_link")).translation
    for normalized, expected in ((True, math.exp(-1.0)), (False, math.exp(-(0.3**3) / 0.3))):
        task = SelfCollisionTask(
            model, "gripper_left_base_link",
            [RepulsionPoint("universe", 0.2, tuple(gripper + [0.3, 0.0, 0.0]))], radius=0.1, kp=1.0,
            normalized=normalized,
        )
        assert task.values(model, data)[0] == pytest.approx(expected)
        np.testing.assert_allclose(task.influence_radii, [0.3])


def test_cache_follows_the_configuration(erd_talos):
    model = erd_talos.model
    data = model.createData()
    task = _task(model)
    qa, va = erd_talos.random_state(1)
    qb, vb = erd_talos.random_state(2)
    erd_talos.at(data, qa, va)
    ja, da = task.jacobian(model, data), task.drift(model, data)
    erd_talos.at(data, qb, vb)
    jb = task.jacobian(model, data)
    assert not np.allclose(ja, jb)
    erd_talos.at(data, qa, vb)  # same q, other v: Jacobian reused, drift recomputed
    np.testing.assert_array_equal(task.jacobian(model, data), ja)
    assert not np.allclose(task.drift(model, data), da)


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"exponent": 1.5}, "exponent"),
        ({"radius": -0.1}, "radius"),
        ({"offset": (0.0, 0.0)}, "offset"),
        ({"kp": -1.0}, "kp"),
        ({"mask": [1, 1]}, "mask"),
    ],
)
def test_invalid_arguments_name_the_key(erd_talos, kwargs, key):
    with pytest.raises(TaskConfigError) as info:
        _task(erd_talos.model, **kwargs)
    assert info.value.key == key


def test_invalid_repulsors(erd_talos):
    model = erd_talos.model
    with pytest.raises(TaskConfigError, match="repulsors"):
        SelfCollisionTask(model, "gripper_left_base_link", [], radius=0.1, kp=1.0)
    with pytest.raises(UnknownNameError, match="torso_2_lnk"):
        SelfCollisionTask(model, "gripper_left_base_link", [RepulsionPoint("torso_2_lnk", 0.1)], radius=0.1, kp=1.0)
    with pytest.raises(TaskConfigError, match="> 0"):
        SelfCollisionTask(model, "gripper_left_base_link", [RepulsionPoint("torso_2_link", 0.0)], radius=0.0, kp=1.0)
    with pytest.raises(TaskConfigError, match="twice"):
        SelfCollisionTask(
            model, "gripper_left_base_link",
            [RepulsionPoint("torso_2_link", 0.1, name="a"), RepulsionPoint("base_link", 0.1, name="a")],
            radius=0.1, kp=1.0,
        )
    two = SelfCollisionTask(
        model, "gripper_left_base_link",
        [RepulsionPoint("base_link", 0.1, (0, 0.1, 0)), RepulsionPoint("base_link", 0.1, (0, -0.1, 0))],
        radius=0.1, kp=1.0,
    )
    assert two.axis_names == ("base_link#1", "base_link#2")
    assert two.name == "self_collision-gripper_left_base_link"


@pytest.mark.parametrize("seed", [5, 9])
def test_position_kernel_matches_the_numpy_reference(erd_talos, seed):
    """The compiled position kernel and a numpy reference (tests/tasks/self_collision_reference.py) give the same
    rows, and so the same values, Jacobian, velocity and drift."""
    from .self_collision_reference import reference_evaluate

    model = erd_talos.model
    q, v = erd_talos.random_state(seed)
    data = erd_talos.at(model.createData(), q, v)
    a = _task(model, normalized=True, radius=0.3, negligible=1e-6)
    b = _task(model, normalized=True, radius=0.3, negligible=1e-6)
    reference_evaluate(b, model, data)  # b's cache now holds the reference's quantities
    for name in ("values", "distances", "jacobian", "velocity", "drift"):
        np.testing.assert_allclose(getattr(a, name)(model, data), getattr(b, name)(model, data), rtol=1e-10,
                                   atol=1e-12, err_msg=name)


@pytest.mark.parametrize("seed", [5, 9])
def test_velocity_kernel_matches_the_numpy_reference(erd_talos, seed):
    """The compiled velocity kernel (point velocities from the world Jacobians) and a numpy reference with
    pinocchio's joint velocities and accelerations give the same C_dot and drift, with several repulsors active."""
    from .self_collision_reference import reference_velocity

    model = erd_talos.model
    q, v = erd_talos.random_state(seed)
    data = erd_talos.at(model.createData(), q, v)
    task = _task(model, normalized=True, radius=0.3, negligible=1e-6)
    velocity, drift = reference_velocity(_task(model, normalized=True, radius=0.3, negligible=1e-6), model, data)
    assert np.count_nonzero(drift) >= 2
    np.testing.assert_allclose(task.velocity(model, data), velocity, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(task.drift(model, data), drift, rtol=1e-10, atol=1e-12)
