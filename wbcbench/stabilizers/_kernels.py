"""Compiled kernels of the force-based stabilizer's tick (stabilizers/teleop.py, see :mod:`wbcbench.jit`): the
feet's measured normal forces, CoPs and ZMP from the ankle F/T sensors, and the split of a reference ZMP between
the feet as the QP's wrench variables (Eq. 6 on the cart-table ZMP, `reference_wrench_targets`).

One implementation each: with ``WBCBENCH_JIT=0`` the same functions run as plain Python. The tests check them
against the module's numpy laws (`measured_wrench`, `zmp_distributor`, `split_to_local`), written per foot with
pinocchio (tests/stabilizers/test_teleop_stabilizer.py).
"""

from __future__ import annotations

import numpy as np

from ..jit import njit

__all__ = ["feet_measurement", "reference_split"]


@njit
def feet_measurement(R_sensor, p_sensor, f_sensor, m_sensor, foot_mass, foot_com, R_sole, p_sole, sole_center,
                     min_normal_force, gravity, out, zmp):
    """Per foot i (rows 0, 1: left, right), from its ankle F/T reading ``f_sensor[i]``, ``m_sensor[i]`` (3,) [N,
    N m] at the sensor placement ``R_sensor[i]`` (3, 3), ``p_sensor[i]`` (3,), the ground's wrench on the foot
    (the foot below the sensor, ``foot_mass[i]`` [kg] with its CoM ``foot_com[i]`` in the sensor frame, removed:
    `measured_wrench`); writes ``out[i] = [f_z, c_x, c_y]``: the normal force [N] and, when ``f_z >=
    min_normal_force`` and ``f_z > 0``, the CoP in the sole frame (``R_sole[i]``, ``p_sole[i]``) relative to
    the sole centre ``sole_center`` (3,, sole frame) [m], else NaN. ``zmp`` (2,) [m]: the ZMP (world x y) of the
    feet whose ``f_z >= min_normal_force``, about the height of the lower sole; NaN when their total force is not
    positive."""
    ground = min(p_sole[0, 2], p_sole[1, 2])
    fz_t = mx_t = my_t = 0.0
    F = np.empty(3)
    M = np.empty(3)
    for i in range(2):
        mg = foot_mass[i] * gravity
        for a in range(3):
            F[a] = -(R_sensor[i, a, 0] * f_sensor[i, 0] + R_sensor[i, a, 1] * f_sensor[i, 1]
                     + R_sensor[i, a, 2] * f_sensor[i, 2])
            M[a] = -(R_sensor[i, a, 0] * m_sensor[i, 0] + R_sensor[i, a, 1] * m_sensor[i, 1]
                     + R_sensor[i, a, 2] * m_sensor[i, 2])
        F[2] += mg
        c0 = R_sensor[i, 0, 0] * foot_com[i, 0] + R_sensor[i, 0, 1] * foot_com[i, 1] + R_sensor[i, 0, 2] * foot_com[i, 2]
        c1 = R_sensor[i, 1, 0] * foot_com[i, 0] + R_sensor[i, 1, 1] * foot_com[i, 1] + R_sensor[i, 1, 2] * foot_com[i, 2]
        M[0] += mg * c1
        M[1] -= mg * c0
        fz = F[2]
        out[i, 0] = fz
        out[i, 1] = out[i, 2] = np.nan
        rx, ry = p_sensor[i, 0], p_sensor[i, 1]
        if fz >= min_normal_force and fz > 0.0:
            # moment about the sole origin's height, then the CoP in the sole frame
            rz = p_sensor[i, 2] - p_sole[i, 2]
            mx = M[0] + ry * F[2] - rz * F[1]
            my = M[1] + rz * F[0] - rx * F[2]
            d0 = -my / fz - p_sole[i, 0]
            d1 = mx / fz - p_sole[i, 1]
            d2 = p_sole[i, 2] - p_sole[i, 2]
            out[i, 1] = R_sole[i, 0, 0] * d0 + R_sole[i, 1, 0] * d1 + R_sole[i, 2, 0] * d2 - sole_center[0]
            out[i, 2] = R_sole[i, 0, 1] * d0 + R_sole[i, 1, 1] * d1 + R_sole[i, 2, 1] * d2 - sole_center[1]
        if fz >= min_normal_force:
            rz = p_sensor[i, 2] - ground
            fz_t += fz
            mx_t += M[0] + ry * F[2] - rz * F[1]
            my_t += M[1] + rz * F[0] - rx * F[2]
    if fz_t > 0.0:
        zmp[0] = -my_t / fz_t
        zmp[1] = mx_t / fz_t
    else:
        zmp[0] = zmp[1] = np.nan


@njit
def reference_split(com, com_acc, R_left, p_left, R_right, p_right, sole_center, mass, gravity, out):
    """`reference_wrench_targets` with both feet in contact: the cart-table ZMP of the CoM reference ``com``,
    ``com_acc`` (3,) [m, m/s^2] over the lower sole centre, split between the feet by Eq. 6 (`zmp_distributor`)
    and written as the QP's wrench variables (`split_to_local`): ``out`` (2, 6) [N, N m], rows left, right,
    each in its LOCAL sole frame (``R_*``, ``p_*``) about the sole frame's origin."""
    R = (R_left, R_right)
    p = (p_left, p_right)
    c = np.empty((2, 3))
    for s in range(2):
        for a in range(3):
            c[s, a] = (R[s][a, 0] * sole_center[0] + R[s][a, 1] * sole_center[1] + R[s][a, 2] * sole_center[2]
                       + p[s][a])
    h = com[2] - min(c[0, 2], c[1, 2])
    z0 = com[0] - h / gravity * com_acc[0]
    z1 = com[1] - h / gravity * com_acc[1]
    # Eq. 6: alpha along the left -> right segment, normal forces, the ankle moment tau_0 (x, y)
    s0, s1 = c[1, 0] - c[0, 0], c[1, 1] - c[0, 1]
    L2 = s0 * s0 + s1 * s1
    if L2 > 0.0:
        alpha = min(max(((z0 - c[0, 0]) * s0 + (z1 - c[0, 1]) * s1) / L2, 0.0), 1.0)
    else:
        alpha = 0.5
    mg = mass * gravity
    f = ((1.0 - alpha) * mg, alpha * mg)
    t0 = t1 = 0.0
    for s in range(2):
        t0 += (z1 - c[s, 1]) * f[s]
        t1 += -(z0 - c[s, 0]) * f[s]
    loads_left = t0 > 0.0
    for s in range(2):
        share = f[s] / mg
        mx = t0 if (s == 0) == loads_left else 0.0
        my = share * t1
        # the moment about the sole frame's origin: m + (c - p) x f, f = (0, 0, f_z)
        fz = f[s]
        r0, r1 = c[s, 0] - p[s][0], c[s, 1] - p[s][1]
        m0 = mx + r1 * fz
        m1 = my - r0 * fz
        m2 = 0.0
        for a in range(3):
            out[s, a] = R[s][2, a] * fz
            out[s, 3 + a] = R[s][0, a] * m0 + R[s][1, a] * m1 + R[s][2, a] * m2
    return alpha
