"""Stable PD (Tan et al. 2011) torques of the SPD actuation mode in one compiled call.

The torque is computed before every physics step: the gains act on the position and velocity predicted one step
ahead, with the next acceleration taken from the full dynamics, ``(M + dt Kd) a = -c + f_passive + f_constraint +
f_applied + [p + tau_ff]`` on the actuated degrees of freedom. As numpy calls it cost about 100 us a step (a
dozen array operations and a LAPACK solve); here the same arithmetic and one solve (``np.linalg.solve``, LAPACK's
``gesv`` as numpy's) run compiled.
"""

from __future__ import annotations

import numpy as np

from ..jit import njit

__all__ = ["spd_torque"]


@njit
def spd_torque(M, qpos, qvel, q_idx, v_idx, q_cmd, v_ref, tau_ff, kp, kd, dt, bias, passive, constraint, applied,
               effort, out):
    """The SPD torques (na,) into ``out``, clipped to ``effort``: MuJoCo's full inertia ``M`` (nv, nv) and force
    vectors (nv,) at the current state, the actuated joints' positions / velocities at ``q_idx`` / ``v_idx`` of
    ``qpos`` / ``qvel``, the command ``q_cmd``, ``v_ref`` and ``tau_ff`` (na,; empty: zero) and the gains (na,)."""
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
    acc = np.linalg.solve(A, rhs)
    for i in range(na):
        tau = p[i] - kd[i] * dt * acc[v_idx[i]]
        if tau_ff.shape[0]:
            tau += tau_ff[i]
        e = effort[i]
        out[i] = -e if tau < -e else (e if tau > e else tau)
