"""Compiled kernels of the formulations' ticks (see :mod:`wbcbench.jit`): the inverse-dynamics QP assembly and
torques (id_formulation.py), the IK's velocity bounds (ik_formulation.py).

One implementation each: with ``WBCBENCH_JIT=0`` the same functions run as plain Python. The tests check them
against numpy references of the formulas (tests/test_controller_kernels.py).
"""

from __future__ import annotations

import numpy as np

from collections import namedtuple

from ..jit import njit

__all__ = ["AssemblyRows", "JointLimits", "QPBuffers", "assemble", "ik_bounds", "torques"]

#: The rows of one tick (views of the task stack and pinocchio's data, refilled in place): the weighted tasks'
#: rows and their sqrt(weight)s, the contacts' rows (Jc, also the first rows of A_hard), the equality rows, the
#: floating base's mass-matrix rows and nonlinear effects.
AssemblyRows = namedtuple("AssemblyRows", ["A_cost", "b_cost", "sw", "Jc", "A_hard", "b_hard", "M_base", "nle_base"])
#: The QP's arrays the assembly writes: the acceleration block of H and g, the equalities, the joints' bounds.
QPBuffers = namedtuple("QPBuffers", ["H", "g", "A_eq", "b_eq", "lb_joints", "ub_joints"])
#: Joint limits as acceleration bounds: [q_hi; q_lo] and [v_max; -v_max] (2, na), the position horizon [s] and
#: the control period [s].
JointLimits = namedtuple("JointLimits", ["QL", "VL", "horizon", "dt"])


def assemble(rows, reg_dv, q_joints, v_joints, limits, out):
    """Fill the QP of one tick in place (``rows``: `AssemblyRows`, ``limits``: `JointLimits`, ``out``:
    `QPBuffers`, the buffers of ``id_formulation._Layout``).

    Cost: ``H[:nv, :nv] = Aw' Aw + reg_dv I``, ``g[:nv] = -Aw' (sw * b)`` with ``Aw = sw * A_cost`` (the wrench
    block of ``H`` and of ``g`` is left as it is: constant). Equalities: ``[M_b  -Jc_b'] x = -h_b`` and the hard
    rows (``A_hard``: the contacts', then priority-0 tasks'). Bounds on the joint accelerations:
    ``a_hi = min(2 (q_hi - q - v h) / h^2, (v_max - v) / dt)``, ``a_lo`` likewise, ``a_lo <= a_hi`` enforced.
    """
    _assemble(*rows, reg_dv, q_joints, v_joints, *limits, *out)


# The compiled kernels take their arrays flat: numba types a named tuple argument in Python on every call
# (~2-4 us for a dozen arrays, measured), flat arrays in C (~1 us); the public functions above and below give
# the structure, these the speed.
@njit
def _assemble(A_cost, b_cost, sw, Jc, A_hard, b_hard, M_base, nle_base, reg_dv, q_joints, v_joints, QL, VL, horizon,
              dt, H, g, A_eq, b_eq, lb_joints, ub_joints):
    """`assemble` on flat arrays."""
    m_c, nv = A_cost.shape
    for i in range(nv):
        for j in range(nv):
            H[i, j] = 0.0
        g[i] = 0.0
    row = np.empty(nv)
    for r in range(m_c):
        s = sw[r]
        for i in range(nv):
            row[i] = s * A_cost[r, i]
        bw = -s * b_cost[r]
        for i in range(nv):
            a = row[i]
            if a != 0.0:
                g[i] += a * bw
                for j in range(i + 1):
                    H[i, j] += a * row[j]
    for i in range(nv):
        H[i, i] += reg_dv
        for j in range(i):
            H[j, i] = H[i, j]
    # equalities: floating-base dynamics, then the hard rows
    n = A_eq.shape[1]
    nw = n - nv
    for i in range(6):
        for j in range(nv):
            A_eq[i, j] = M_base[i, j]
        for c in range(nw):
            A_eq[i, nv + c] = -Jc[c, i]
        b_eq[i] = -nle_base[i]
    for r in range(A_hard.shape[0]):
        for j in range(nv):
            A_eq[6 + r, j] = A_hard[r, j]
        b_eq[6 + r] = b_hard[r]
    # joint position and velocity limits as acceleration bounds
    na = q_joints.shape[0]
    c_pos = 2.0 / (horizon * horizon)
    for i in range(na):
        s_ = q_joints[i] + v_joints[i] * horizon
        hi = min(c_pos * (QL[0, i] - s_), (VL[0, i] - v_joints[i]) / dt)
        lo = max(c_pos * (QL[1, i] - s_), (VL[1, i] - v_joints[i]) / dt)
        ub_joints[i] = hi
        lb_joints[i] = min(lo, hi)


@njit
def torques(M_joints, nle_joints, Jc, x, tau_limit):
    """``tau = M_a dv + h_a - J_c,a' w`` for ``x = [dv; w]``, and whether ``|tau| <= tau_limit`` everywhere."""
    na, nv = M_joints.shape
    nw = x.shape[0] - nv
    tau = np.empty(na)
    within = True
    for i in range(na):
        s = nle_joints[i]
        for j in range(nv):
            s += M_joints[i, j] * x[j]
        for c in range(nw):
            s -= Jc[c, 6 + i] * x[nv + c]
        tau[i] = s
        if not abs(s) <= tau_limit[i]:
            within = False
    return tau, within


@njit
def ik_bounds(q_lim, v_max, q_joints, dt, lower, upper):
    """Joint velocity bounds of one IK tick, written into ``lower[6:]``, ``upper[6:]``: the joint position limits
    ``q_lim = [q_lo; q_hi]`` reached in one step, ``(q_lim - q) / dt``, and the velocity limits ``+-v_max``;
    ``lower <= upper`` enforced (a joint beyond a limit may only move back)."""
    for i in range(q_joints.shape[0]):
        lo = max((q_lim[0, i] - q_joints[i]) / dt, -v_max[i])
        hi = min((q_lim[1, i] - q_joints[i]) / dt, v_max[i])
        upper[6 + i] = hi
        lower[6 + i] = min(lo, hi)
    for i in range(6):
        lower[i] = min(lower[i], upper[i])


@njit
def cap_task_accelerations(b, drift, e, v_ref, rows, p):
    """Out-of-reach caps on frame tasks' commanded accelerations, in place on the stacked task rows ``b`` (= a* -
    drift; ``drift``, the errors ``e`` and the reference velocities ``v_ref`` the stack's): per task k, ``rows[k]``
    (6,) the stack rows of its axes x y z roll pitch yaw (-1: not selected). ``p`` = [e0, e1, a_lin, a_ang, v0,
    v1, r0, r1, p0, p1]. Where the task's position error ``|e_xyz|`` exceeds ``e0`` [m] while its reference moves
    faster than ``v0`` [m/s], its commanded linear and angular accelerations ``a* = b + drift`` are scaled towards
    the norms ``a_lin``, ``a_ang`` (only where larger), fully from ``e1`` and ``v1`` on (min-jerk blends in
    between, so that the rows stay continuous); a still target out of reach is left to the task. Where its
    rotation error ``|e_rpy|`` exceeds ``r0`` [rad] (fully from ``r1``; r0 = inf: off), its angular one is, whatever
    the reference's speed (the larger of the two blends), its linear one left to the position trigger; this angular
    trigger lets go as the position error grows from ``p0`` to ``p1`` [m] (a hand far from its position, e.g. held
    off a reference inside the body, keeps its full angular demand). Returns how many tasks were capped."""
    e0, e1, a_lin, a_ang, v0, v1 = p[0], p[1], p[2], p[3], p[4], p[5]
    r0, r1, p0, p1 = p[6], p[7], p[8], p[9]
    n_capped = 0
    for k in range(rows.shape[0]):
        en = 0.0
        vn = 0.0
        rn = 0.0
        for i in range(3):
            r = rows[k, i]
            if r >= 0:
                en += e[r] * e[r]
                vn += v_ref[r] * v_ref[r]
            r = rows[k, 3 + i]
            if r >= 0:
                rn += e[r] * e[r]
        en = np.sqrt(en)
        rn = np.sqrt(rn)
        s = 0.0
        if en > e0:
            s = _smoothstep((en - e0) / (e1 - e0)) * _smoothstep((np.sqrt(vn) - v0) / (v1 - v0))
        s_rot = 0.0
        if rn > r0:
            s_rot = _smoothstep((rn - r0) / (r1 - r0)) * (1.0 - _smoothstep((en - p0) / (p1 - p0)))
        if s <= 0.0 and s_rot <= 0.0:
            continue
        capped = False
        for part in range(2):
            limit = a_lin if part == 0 else a_ang
            sp = s if part == 0 else max(s, s_rot)
            if sp <= 0.0:
                continue
            norm = 0.0
            for i in range(3 * part, 3 * part + 3):
                r = rows[k, i]
                if r >= 0:
                    a = b[r] + drift[r]
                    norm += a * a
            norm = np.sqrt(norm)
            if norm <= limit:
                continue
            f = (1.0 - sp) + sp * limit / norm
            for i in range(3 * part, 3 * part + 3):
                r = rows[k, i]
                if r >= 0:
                    b[r] = (b[r] + drift[r]) * f - drift[r]
            capped = True
        if capped:
            n_capped += 1
    return n_capped


@njit
def _smoothstep(u):
    """The min-jerk blend of u clipped to [0, 1]."""
    u = min(1.0, max(0.0, u))
    return u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
