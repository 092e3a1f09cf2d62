"""Contact6D: LOCAL motion rows against finite differences; wrench cone rows against corner forces."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.tasks import (
    Contact6D,
    ReferenceNotSetError,
    TaskConfigError,
    UnknownNameError,
    acceleration_rows,
    tsid_wrench_metric,
)

SEEDS = st.integers(min_value=0, max_value=2**31 - 1)
SOLE = {"length": 0.20, "width": 0.13}


def _contact(model, **kwargs) -> Contact6D:
    return Contact6D(model, "left_sole_link", **{**SOLE, "kp": 30.0, "kd": 11.0, **kwargs})


# ------------------------------------------------------------------------------------------- motion rows
@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_local_jacobian_error_and_drift_match_finite_differences(erd_talos, seed):
    model = erd_talos.model
    data = model.createData()
    contact = _contact(model)
    q, v = erd_talos.random_state(seed)
    q_ref, _ = erd_talos.random_state(seed + 1)
    contact.set_reference_to_current(model, erd_talos.at(data, q_ref))

    erd_talos.at(data, q, v)
    M0 = contact.placement(model, data)
    J = contact.jacobian(model, data)
    J_fd = erd_talos.numerical_jacobian(
        q, lambda qq: pin.log6(M0.actInv(contact.placement(model, erd_talos.at(data, qq)))).vector
    )
    np.testing.assert_allclose(J, J_fd, atol=1e-6)

    de_fd = erd_talos.numerical_jacobian(q, lambda qq: contact.error(model, erd_talos.at(data, qq)))
    expected = -pin.Jlog6(contact.reference.actInv(M0)) @ J  # d/dt log6(M^-1 M_ref) = -Jlog6(M_ref^-1 M) nu
    # the finite difference's truncation error grows with the error's curvature: a tolerance relative to the rows'
    # size, as for the drift below (a random state's rows reach 1.7 and their difference 1.6e-5)
    np.testing.assert_allclose(de_fd, expected, atol=1e-5 * (1 + np.abs(expected).max()))

    erd_talos.at(data, q, v)
    np.testing.assert_allclose(contact.velocity(model, data), J @ v, atol=1e-10)
    drift = contact.drift(model, data)
    drift_fd = erd_talos.along(q, v, lambda qq: contact.jacobian(model, erd_talos.at(data, qq)) @ v)
    np.testing.assert_allclose(drift, drift_fd, atol=1e-5 * (1 + np.abs(drift_fd).max()))


@settings(max_examples=10, deadline=None)
@given(seed=SEEDS)
def test_classical_drift_is_the_origin_acceleration(erd_talos, seed):
    """drift="classical": the frame origin's acceleration at zero joint acceleration in the frame's axes (the second
    derivative of its world position, rotated), i.e. the spatial drift plus omega x v on the linear rows; the
    angular rows are the spatial ones."""
    model = erd_talos.model
    data = model.createData()
    spatial, classical = _contact(model), _contact(model, drift="classical")
    assert (spatial.drift_convention, classical.drift_convention) == ("spatial", "classical")
    q, v = erd_talos.random_state(seed)
    erd_talos.at(data, q, v)
    nu = spatial.velocity(model, data)
    a = classical.drift(model, data)
    np.testing.assert_allclose(a, spatial.drift(model, data) + np.r_[np.cross(nu[3:], nu[:3]), np.zeros(3)],
                               atol=1e-12 * (1 + np.abs(a).max()))
    R = classical.placement(model, data).rotation
    h = 1e-5  # the world position's second derivative along q(t) = q + t v (zero joint acceleration)

    def origin(t):
        return classical.placement(model, erd_talos.at(data, pin.integrate(model, q, t * v))).translation

    p_ddot = (origin(h) - 2 * origin(0.0) + origin(-h)) / h**2
    np.testing.assert_allclose(R.T @ p_ddot, a[:3], atol=1e-3 * (1 + np.abs(a[:3]).max()))


def test_tsid_wrench_metric_is_tsids_cost(erd_talos):
    """`tsid_wrench_metric`: w^T W w is TSID's cost of the wrench w, weight ||diag(a) w_T||^2 at TSID's frame plus
    eps times the squared norm of the least-norm corner forces making w (computed here by least squares)."""
    contact = _contact(erd_talos.model)
    rng = np.random.default_rng(5)
    a = np.array([1.0, 1.0, 1e-3, 2.0, 2.0, 2.0])
    ankle = pin.SE3(pin.exp3(np.array([0.0, 0.05, 0.1])), np.array([0.01, 0.0, 0.107]))  # TSID's frame in the sole's
    G = contact.corner_wrench_map()
    for frame in (None, ankle):
        W = tsid_wrench_metric(contact.corners, weight=1e-5, axis_weights=a, corner_regularization=1e-8,
                               tsid_frame=frame)
        assert np.array_equal(W, W.T) and np.linalg.eigvalsh(W).min() > 0
        for _ in range(5):
            w = rng.normal(size=6) * [50, 50, 400, 20, 20, 5]
            w_T = w if frame is None else frame.actInv(pin.Force(w)).vector
            f = np.linalg.lstsq(G, w, rcond=None)[0]
            cost = 1e-5 * np.sum((a * w_T) ** 2) + 1e-8 * f @ f
            assert np.isclose(w @ W @ w, cost, rtol=1e-12)
    # the ankle frame couples the sole's forces and moments
    assert np.abs(W[:3, 3:]).max() > 1e-3 * np.abs(W).max()


def test_motion_rows_keep_the_sole_still(erd_talos):
    model = erd_talos.model
    q, v = erd_talos.random_state(8)
    data = erd_talos.at(model.createData(), q, v)
    contact = _contact(model)
    with pytest.raises(ReferenceNotSetError):
        contact.error(model, data)
    contact.set_reference_to_current(model, data)
    A, b = acceleration_rows(contact, model, data)
    np.testing.assert_array_equal(A, contact.jacobian(model, data))
    np.testing.assert_allclose(b, -contact.drift(model, data) - 11.0 * (A @ v), atol=1e-10)
    erd_talos.at(data, q, np.zeros(model.nv))
    np.testing.assert_allclose(acceleration_rows(contact, model, data).b, 0.0, atol=1e-12)


def test_a_pose_reference_sets_what_an_se3_sets_and_bad_poses_are_refused(erd_talos):
    """A stabilizer's per-tick contact pose may be a PoseReference (no SE3 made): the same reference, the same
    rows, the same checks."""
    from wbcbench.types import PoseReference

    model = erd_talos.model
    q, v = erd_talos.random_state(3)
    data = erd_talos.at(model.createData(), q, v)
    M = pin.SE3(pin.rpy.rpyToMatrix(0.05, -0.03, 0.4), np.array([0.1, 0.2, 0.01]))
    by_se3, by_pose = _contact(model), _contact(model)
    by_se3.set_reference(M)
    by_pose.set_reference(PoseReference(M.translation.copy(), M.rotation.copy()))
    np.testing.assert_array_equal(by_pose.reference.homogeneous, by_se3.reference.homogeneous)
    for a, b in zip(acceleration_rows(by_pose, model, data), acceleration_rows(by_se3, model, data)):
        np.testing.assert_array_equal(a, b)
    bad_R = M.rotation.copy()
    bad_R[0, 0] += 0.1
    for pose, what in ((PoseReference(M.translation.copy(), bad_R), "rigid"),
                       (PoseReference(M.translation.copy()), "position and a rotation"),
                       ("pose", "position and a rotation")):
        with pytest.raises(TaskConfigError, match=what):
            by_pose.set_reference(pose)
    np.testing.assert_array_equal(by_pose.reference.homogeneous, M.homogeneous)  # a refused pose changes nothing


# -------------------------------------------------------------------------------------------- force rows
def _corner_forces(draw_fz, draw_dir, mu):
    """Corner forces inside the inscribed pyramid |fx|, |fy| <= mu fz."""
    forces = []
    for fz, (a, b) in zip(draw_fz, draw_dir, strict=True):
        forces += [a * mu * fz, b * mu * fz, fz]
    return np.array(forces)


CORNER = st.tuples(st.floats(0.0, 500.0), st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)))


@settings(max_examples=60, deadline=None)
@given(
    corners=st.lists(CORNER, min_size=4, max_size=4),
    center=st.tuples(st.floats(-0.05, 0.05), st.floats(-0.03, 0.03)),
)
def test_wrenches_from_corner_forces_are_inside(erd_talos, corners, center):
    contact = _contact(erd_talos.model, center=center, max_normal_force=1e4)
    fz = [c[0] for c in corners]
    f = _corner_forces(fz, [c[1] for c in corners], contact.mu_pyramid)
    w = contact.corner_wrench_map() @ f
    assert contact.inside(w, tol=1e-6)


@settings(max_examples=60, deadline=None)
@given(w=st.tuples(*[st.floats(-1.0, 1.0)] * 6), center=st.tuples(st.floats(-0.05, 0.05), st.floats(-0.03, 0.03)))
def test_inside_wrenches_decompose_into_corner_forces(erd_talos, w, center):
    """Converse: a wrench accepted by C w <= u is generated by pyramid corner forces (checked by LP)."""
    from scipy.optimize import linprog

    contact = _contact(erd_talos.model, center=center)
    wrench = np.array(w) * [100, 100, 0, 20, 20, 10] + [0, 0, 800, 0, 0, 0]
    if not contact.inside(wrench):
        return
    mu = contact.mu_pyramid
    pyramid = np.array([[1, 0, -mu], [-1, 0, -mu], [0, 1, -mu], [0, -1, -mu], [0, 0, -1]])
    A_ub = np.kron(np.eye(4), pyramid)
    result = linprog(
        np.zeros(12),
        A_ub=A_ub,
        b_ub=np.zeros(20),
        A_eq=contact.corner_wrench_map(),
        b_eq=wrench,
        bounds=[(None, None)] * 12,
        method="highs",
    )
    assert result.status == 0


def test_force_rows_reject_wrenches_outside(erd_talos):
    contact = _contact(erd_talos.model, center=(0.02, 0.0), min_normal_force=10.0, max_normal_force=1000.0)
    fz = 500.0
    mu = contact.mu_pyramid
    assert contact.inside([0, 0, fz, 0, 0, 0])
    assert contact.inside([0.99 * mu * fz, 0, fz, 0, 0, 0])
    assert not contact.inside([1.01 * mu * fz, 0, fz, 0, 0, 0])  # friction
    assert not contact.inside([0, -1.01 * mu * fz, fz, 0, 0, 0])
    # CoP: x in [0.02 - 0.10, 0.02 + 0.10], y in [-0.065, 0.065]; CoP x = -tau_y / fz, CoP y = tau_x / fz
    assert contact.inside([0, 0, fz, 0, -0.119 * fz, 0])
    assert not contact.inside([0, 0, fz, 0, -0.121 * fz, 0])
    assert contact.inside([0, 0, fz, 0, 0.079 * fz, 0])
    assert not contact.inside([0, 0, fz, 0, 0.081 * fz, 0])
    assert contact.inside([0, 0, fz, 0.064 * fz, 0, 0])
    assert not contact.inside([0, 0, fz, -0.066 * fz, 0, 0])
    np.testing.assert_allclose(contact.cop([0, 0, fz, 0.05 * fz, -0.1 * fz, 0]), [0.1, 0.05])
    # yaw torque: at most mu (X + Y) fz with the CoP at the sole centre (tau_y = -c_x fz at the origin) and
    # no tangential force; less with the CoP elsewhere
    tz_max = mu * (0.10 + 0.065) * fz
    ty = -0.02 * fz
    assert contact.inside([0, 0, fz, 0, ty, 0.99 * tz_max])
    assert contact.inside([0, 0, fz, 0, ty, -0.99 * tz_max])
    assert not contact.inside([0, 0, fz, 0, ty, 1.01 * tz_max])
    assert not contact.inside([0, 0, fz, 0, ty, -1.01 * tz_max])
    assert not contact.inside([0, 0, fz, 0, 0.0, 0.99 * tz_max])
    # normal force bounds
    assert not contact.inside([0, 0, 9.0, 0, 0, 0])
    assert not contact.inside([0, 0, 1001.0, 0, 0, 0])
    assert not contact.inside([0, 0, -1.0, 0, 0, 0])
    C, u = contact.force_rows()
    assert C.shape == (18, 6) and u.shape == (18,) and len(contact.FORCE_ROW_NAMES) == 18


def test_set_max_force_ramps_the_contact_out(erd_talos):
    contact = _contact(erd_talos.model, min_normal_force=20.0, max_normal_force=1500.0)
    _, u_before = contact.force_rows()
    contact.set_max_force(100.0)
    assert contact.max_normal_force == 100.0 and contact.min_normal_force == 20.0
    assert not contact.inside([0, 0, 150.0, 0, 0, 0])
    contact.set_max_force(10.0)
    assert contact.min_normal_force == 10.0  # the lower bound follows, so the rows stay feasible
    assert contact.inside([0, 0, 10.0, 0, 0, 0])
    contact.set_max_force(0.0)
    assert contact.inside(np.zeros(6))
    for k in range(6):
        e = np.zeros(6)
        e[k] = 1e-3
        assert not contact.inside(e, tol=0.0) or not contact.inside(-e, tol=0.0)
    assert u_before[-1] == 1500.0  # earlier results are not mutated
    contact.set_max_force(contact.nominal_max_normal_force)
    assert contact.max_normal_force == 1500.0 and contact.min_normal_force == 20.0
    with pytest.raises(TaskConfigError, match="max_normal_force"):
        contact.set_max_force(-1.0)


def test_corners_and_friction_coefficients(erd_talos):
    contact = _contact(erd_talos.model, center=(0.01, -0.02), mu=0.5)
    np.testing.assert_allclose(contact.corners[0], [0.11, 0.045, 0.0])
    np.testing.assert_allclose(contact.corners[3], [-0.09, -0.085, 0.0])
    assert contact.mu_pyramid == pytest.approx(0.5 / math.sqrt(2.0))


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"length": 0.0}, "length"),
        ({"width": -0.1}, "width"),
        ({"mu": 0.0}, "mu"),
        ({"center": (0.0,)}, "center"),
        ({"min_normal_force": -1.0}, "min_normal_force"),
        ({"min_normal_force": 100.0, "max_normal_force": 50.0}, "max_normal_force"),
        ({"kp": -30.0}, "kp"),
        ({"weight": -1.0}, "weight"),
        ({"drift": "exact"}, "drift"),
        ({"wrench_metric": np.eye(3)}, "wrench_metric"),
        ({"wrench_metric": np.diag([1.0, 1.0, 1.0, 1.0, 1.0, -1e-3])}, "wrench_metric"),
        ({"wrench_metric": np.eye(6) + np.eye(6, k=1)}, "wrench_metric"),
    ],
)
def test_bad_contact_definitions(erd_talos, kwargs, key):
    with pytest.raises(TaskConfigError) as info:
        _contact(erd_talos.model, **kwargs)
    assert info.value.key == key and "Contact6D 'left_sole_link'" in str(info.value)


def test_unknown_contact_frame(erd_talos):
    with pytest.raises(UnknownNameError, match="left_sole_link"):
        Contact6D(erd_talos.model, "left_sole", kp=30.0, **SOLE)
