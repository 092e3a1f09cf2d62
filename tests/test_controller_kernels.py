"""The controllers' compiled kernels (wbcbench/controllers/_kernels.py: the inverse-dynamics QP assembly and
torques, the IK's velocity bounds) against plain numpy references written here, on TALOS ticks at random states.

The references are the formulas of the formulations' docstrings, written with numpy: they live in the tests only
(the package has one implementation of each kernel)."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.controllers.ik import IKController
from wbcbench.controllers.inverse_dynamics import TSIDTorque
from wbcbench.types import ActuationMode, PointReference, References


def reference_assembly(F, L, q, v):
    """H_dv, g_dv, A_eq, b_eq, lb_joints, ub_joints of one tick, from the formulation's rows (numpy)."""
    nv = F.nv
    Aw = L.A_cost * L.sw[:, None]
    bw = L.b_cost * L.sw
    H = Aw.T @ Aw + F.regularization_dv * np.eye(nv)
    g = -Aw.T @ bw
    A_eq = np.vstack([np.hstack([L.M_base, -L.Jc[:, :6].T]),
                      np.hstack([L.A_hard, np.zeros((L.A_hard.shape[0], L.Jc.shape[0]))])])
    b_eq = np.concatenate([-L.nle_base, L.b_hard])
    h, dt = F.joint_limit_horizon, F.dt
    qj, vj = q[7:], v[6:]
    hi = np.minimum(2 * (F.q_hi - qj - vj * h) / h**2, (F.v_max - vj) / dt)
    lo = np.maximum(2 * (F.q_lo - qj - vj * h) / h**2, (-F.v_max - vj) / dt)
    return H, g, A_eq, b_eq, np.minimum(lo, hi), hi


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_id_assembly_and_torques_match_numpy(talos, seed):
    rng = np.random.default_rng(seed)
    ctrl = TSIDTorque(talos, ActuationMode.TORQUE, 1e-3)
    F = ctrl.formulation
    q = talos.q0.copy()
    q[7:] += 0.05 * rng.standard_normal(talos.na)
    v = 0.3 * rng.standard_normal(talos.nv)
    F.update(q, v)
    F.reset_references(talos.q0, {s for s in F.names})
    ctrl.references.apply(References(t=0.0, com=PointReference(F.data.com[0] + [0.01, -0.02, 0.0])))
    if seed == 2:  # a single contact: the other foot's swing task in the cost, 6 fewer wrench variables
        F.contacts[F.names[1]].active = False
        F.active = F.names[:1]
    P = F.problem()
    L = F._layout
    H, g, A_eq, b_eq, lb, ub = reference_assembly(F, L, q, v)
    nv = F.nv
    scale = np.abs(H).max()
    np.testing.assert_allclose(P.H[:nv, :nv], H, atol=1e-12 * scale, rtol=0)
    np.testing.assert_allclose(P.g[:nv], g, atol=1e-12 * max(1.0, np.abs(g).max()), rtol=0)
    np.testing.assert_allclose(P.A_eq, A_eq, atol=1e-12, rtol=0)
    np.testing.assert_allclose(P.b_eq, b_eq, atol=1e-12, rtol=0)
    np.testing.assert_allclose(P.lb[6:nv], lb, rtol=1e-12)
    np.testing.assert_allclose(P.ub[6:nv], ub, rtol=1e-12)
    x = rng.standard_normal(P.H.shape[0])
    tau, within = F.torques(x)
    expected = L.M_joints @ x[:nv] + L.nle_joints - L.Jc[:, 6:].T @ x[nv:]
    np.testing.assert_allclose(tau, expected, atol=1e-10 * np.abs(expected).max(), rtol=0)
    assert within == bool(np.all(np.abs(expected) <= F.tau_max * (1 + 1e-9)))


def test_wrench_targets_enter_the_cost(talos):
    """w_f ||w - w*||^2 on the wrench variables: H's wrench diagonal r_w + w_f, g = -w_f w*; gone without targets."""
    ctrl = TSIDTorque(talos, ActuationMode.TORQUE, 1e-3)
    F = ctrl.formulation
    F.wrench_target_weight = 0.01
    F.update(talos.q0, np.zeros(talos.nv))
    F.reset_references(talos.q0, set(F.names))
    targets = {s: np.arange(6.0) + i for i, s in enumerate(F.names)}
    F.set_wrench_targets(targets)
    P = F.problem()
    nv = F.nv
    # the regularisation's diagonal per wrench axis (the task set's `regularization.wrench_axes`), every contact
    reg = np.tile(F.wrench_regularization_diagonal, len(F.names))
    np.testing.assert_allclose(np.diag(P.H)[nv:], reg + 0.01)
    np.testing.assert_allclose(P.g[nv:], -0.01 * np.concatenate([targets[s] for s in F.names]))
    F.set_wrench_targets(None)
    P = F.problem()
    np.testing.assert_allclose(np.diag(P.H)[nv:], reg)
    assert not P.g[nv:].any()


@pytest.mark.parametrize("seed", [0, 1])
def test_ik_bounds_match_numpy(talos, seed):
    rng = np.random.default_rng(seed)
    ctrl = IKController(talos, ActuationMode.POSITION, 1e-3)
    K = ctrl.formulation
    q = talos.q0.copy()
    q[7:] += 0.5 * rng.standard_normal(talos.na)  # some joints beyond their limits
    lower, upper = K.bounds(q)
    qj, dt = q[7:], K.dt
    hi = np.minimum((K.q_hi - qj) / dt, K.v_max)
    lo = np.minimum(np.maximum((K.q_lo - qj) / dt, -K.v_max), hi)
    np.testing.assert_allclose(upper[6:], hi, rtol=1e-14)
    np.testing.assert_allclose(lower[6:], lo, rtol=1e-14)
    assert np.all(lower <= upper)


def test_model_feedback_of_tick_is_the_constructors():
    from wbcbench.side import Side
    from wbcbench.types import ModelFeedback

    q, active, wrenches, poses = np.arange(5.0), frozenset({Side.LEFT}), {Side.LEFT: np.ones(6)}, {Side.LEFT: 1}
    assert ModelFeedback.of_tick(q, active, wrenches, poses) == ModelFeedback(q, active, wrenches, poses)
    a, b = ModelFeedback.of_tick(q, active), ModelFeedback.of_tick(q, active)
    assert a == ModelFeedback(q, active)
    assert a.wrenches is not b.wrenches and a.contact_references is not b.contact_references  # dicts of their own
