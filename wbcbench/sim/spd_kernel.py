"""Stable PD (Tan et al. 2011) torques of the SPD actuation mode in one compiled call.

The torque is computed before every physics step: the gains act on the position and velocity predicted one step
ahead, with the next acceleration taken from the full dynamics, ``(M + dt Kd) a = -c + f_passive + f_constraint +
f_applied + [p + tau_ff]`` on the actuated degrees of freedom. As numpy calls it cost about 100 us a step (a
dozen array operations and a LAPACK solve); here the same arithmetic runs compiled, and the solve uses the
kinematic tree: ``M + dt Kd`` has a non-zero ``(i, j)`` only when degree of freedom ``j`` is ``i``'s or one of its
ancestors' (MuJoCo's ``dof_parentid``), so its ``L^T D L`` factorisation (Featherstone, Rigid Body Dynamics
Algorithms, Section 6.5) touches only those entries: on TALOS (38 degrees of freedom) 4.7 us against 11.5 us for
LAPACK's ``gesv`` (``np.linalg.solve``, the same solution to rounding: 5e-15 on 14).
"""

from __future__ import annotations

import numpy as np

from ..jit import njit

__all__ = ["spd_torque"]


@njit
def spd_torque(M, parent, qpos, qvel, q_idx, v_idx, q_cmd, v_ref, tau_ff, kp, kd, dt, bias, passive, constraint,
               applied, effort, out):
    """The SPD torques (na,) into ``out``, clipped to ``effort``: MuJoCo's full inertia ``M`` (nv, nv) and force
    vectors (nv,) at the current state, each degree of freedom's parent ``parent`` (nv,: MuJoCo's
    ``dof_parentid``, -1 at the root, every parent before its child), the actuated joints' positions /
    velocities at ``q_idx`` / ``v_idx`` of ``qpos`` / ``qvel``, the command ``q_cmd``, ``v_ref`` and ``tau_ff``
    (na,; empty: zero) and the gains (na,)."""
    na = q_idx.shape[0]
    nv = M.shape[0]
    A = M.copy()
    rhs = np.empty(nv)
    for i in range(nv):
        rhs[i] = -bias[i] + passive[i] + constraint[i] + applied[i]
    p = np.empty(na)
    for i in range(na):
        q = qpos[q_idx[i]]
        v = qvel[v_idx[i]]
        vr = v_ref[i] if v_ref.shape[0] else 0.0
        p[i] = kp[i] * (q_cmd[i] - q - dt * v) + kd[i] * (vr - v)
        j = v_idx[i]
        A[j, j] += dt * kd[i]
        rhs[j] += p[i] + (tau_ff[i] if tau_ff.shape[0] else 0.0)
    acc = _tree_solve(A, parent, rhs)
    for i in range(na):
        tau = p[i] - kd[i] * dt * acc[v_idx[i]]
        if tau_ff.shape[0]:
            tau += tau_ff[i]
        e = effort[i]
        out[i] = -e if tau < -e else (e if tau > e else tau)


@njit
def _tree_solve(A, parent, b):
    """``x`` with ``A x = b`` for a symmetric positive-definite ``A`` (n, n) whose ``(i, j)`` is zero unless ``j``
    is ``i``, an ancestor of ``i`` in ``parent`` or the reverse: ``A`` is overwritten with its ``L^T D L``
    factors (unit ``L`` below the diagonal, on the ancestors' entries; ``D`` on the diagonal), leaves first."""
    n = A.shape[0]
    for k in range(n - 1, -1, -1):
        i = parent[k]
        while i >= 0:
            a = A[k, i] / A[k, k]
            j = i
            while j >= 0:
                A[i, j] -= a * A[k, j]
                j = parent[j]
            A[k, i] = a
            i = parent[i]
    x = b.copy()
    for i in range(n - 1, -1, -1):  # L^T y = b
        j = parent[i]
        while j >= 0:
            x[j] -= A[i, j] * x[i]
            j = parent[j]
    for i in range(n):  # D z = y
        x[i] /= A[i, i]
    for i in range(n):  # L x = z
        j = parent[i]
        while j >= 0:
            x[i] -= A[i, j] * x[j]
            j = parent[j]
    return x
