"""Compiled kernels of the force-based stabilizer's tick (stabilizers/teleop.py, see :mod:`wbcbench.jit`): the
feet's measured normal forces, CoPs and ZMP from the ankle F/T sensors, and the split of a reference ZMP between
the feet as the QP's wrench variables (Eq. 6 on the cart-table ZMP, `reference_wrench_targets`).

One implementation each: with ``WBCBENCH_JIT=0`` the same functions run as plain Python. The tests check them
against the module's numpy laws (`measured_wrench`, `zmp_distributor`, `split_to_local`), written per foot with
pinocchio (tests/stabilizers/test_teleop_stabilizer.py).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from ..tasks.placements import frame_placements, joint_placements

__all__ = ["ankle_admittance", "com_admittance", "corrections", "feet_measurement", "filter_measurement", "model_cop",
           "reference_split", "torso_roll"]


@njit
def feet_measurement(R_sensor, p_sensor, f_sensor, m_sensor, foot_mass, foot_com, R_sole, p_sole, sole_center,
                     min_normal_force, gravity, out, zmp):
    """Per foot i (rows 0, 1: left, right), from its ankle F/T reading ``f_sensor[i]``, ``m_sensor[i]`` (3,) [N,
    N m] at the sensor placement ``R_sensor[i]`` (3, 3), ``p_sensor[i]`` (3,), the ground's wrench on the foot
    (the foot below the sensor, ``foot_mass[i]`` [kg] with its CoM ``foot_com[i]`` in the sensor frame, removed:
    `measured_wrench`); writes ``out[i] = [f_z, c_x, c_y, loaded]``: the normal force [N] and, when loaded
    (``f_z >= min_normal_force`` and ``f_z > 0``: 1.0, else 0.0), the CoP in the sole frame (``R_sole[i]``,
    ``p_sole[i]``) relative to the sole centre ``sole_center`` (3,, sole frame) [m], else NaN. ``zmp`` (2,) [m]:
    the ZMP (world x y) of the feet whose ``f_z >= min_normal_force``, about the height of the lower sole; returns
    whether it exists (their total force positive; ``zmp`` NaN otherwise)."""
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
        out[i, 3] = 0.0
        rx, ry = p_sensor[i, 0], p_sensor[i, 1]
        if fz >= min_normal_force and fz > 0.0:
            out[i, 3] = 1.0
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
        return True
    zmp[0] = zmp[1] = np.nan
    return False


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


@njit
def _low_pass(state, start, n, u0, u1, alpha, started, k):
    """A first-order low-pass ``y += alpha (u - y)`` on ``y = state[start:start + n]`` (n = 1 or 2, input
    ``u0[, u1]``), ``started[k]`` False until the first input (taken as it is): a non-finite state restarts from
    the input, a non-finite input is skipped."""
    if not started[k]:
        state[start] = u0
        if n == 2:
            state[start + 1] = u1
        started[k] = True
        return
    y_sum = state[start] + (state[start + 1] if n == 2 else 0.0)
    u_sum = u0 + (u1 if n == 2 else 0.0)
    if not math.isfinite(y_sum):
        state[start] = u0
        if n == 2:
            state[start + 1] = u1
    elif math.isfinite(u_sum):
        state[start] += alpha * (u0 - state[start])
        if n == 2:
            state[start + 1] += alpha * (u1 - state[start + 1])


@njit
def filter_measurement(raw, zmp, zmp_ok, alpha, state, started):
    """The first-order low-pass filters of the stabilizer's measurement (`_low_pass`, gain ``alpha``: `teleop.low_pass_gain`) on
    `feet_measurement`'s ``raw`` (2, 4), ``zmp`` (2,) and its return ``zmp_ok``: ``state`` (8,) holds the filtered [ZMP x y, left CoP x y,
    right CoP x y, left normal force, right normal force] and ``started`` (5,) which filter has had an input
    (ZMP, left CoP, right CoP, left, right force). The normal forces (clipped at 0) are filtered every tick, a CoP
    when its foot is loaded, the ZMP when it exists."""
    for i in range(2):
        _low_pass(state, 6 + i, 1, max(raw[i, 0], 0.0), 0.0, alpha, started, 3 + i)
        if raw[i, 3] != 0.0:
            _low_pass(state, 2 + 2 * i, 2, raw[i, 1], raw[i, 2], alpha, started, 1 + i)
    if zmp_ok:
        _low_pass(state, 0, 2, zmp[0], zmp[1], alpha, started, 0)


@njit
def model_cop(R, p, w, use, out):
    """The ZMP (world x y, ``out`` (2,)) [m] of the contact wrenches ``w`` (2, 6) (LOCAL frame of the contact
    placements ``R`` (2, 3, 3), ``p`` (2, 3), about their origins) of the contacts with ``use[i]`` and a positive
    normal force; False (``out`` untouched) when their total normal force is 1 N or less."""
    fz_t = mx_t = my_t = 0.0
    f = np.empty(3)
    m = np.empty(3)
    for i in range(2):
        if not use[i] or not w[i, 2] > 0.0:
            continue
        for a in range(3):
            f[a] = R[i, a, 0] * w[i, 0] + R[i, a, 1] * w[i, 1] + R[i, a, 2] * w[i, 2]
            m[a] = R[i, a, 0] * w[i, 3] + R[i, a, 1] * w[i, 4] + R[i, a, 2] * w[i, 5]
        rx, ry, rz = p[i, 0], p[i, 1], p[i, 2]
        fz_t += f[2]
        mx_t += m[0] + ry * f[2] - rz * f[1]
        my_t += m[1] + rz * f[0] - rx * f[2]
    if fz_t <= 1.0:
        return False
    out[0] = -my_t / fz_t
    out[1] = mx_t / fz_t
    return True


@njit
def com_admittance(p, v, a, e0, e1, kd, kv, ka, limit, dt, out):
    """Paper 004 Eq. 2 (`teleop.com_admittance`): ``out`` (3, 3) = the CoM position, velocity, acceleration
    references ``p``, ``v``, ``a`` (3,) corrected in x-y by the CoP difference ``(e0, e1)`` [m] with the gains
    ``kd``, ``kv``, ``ka`` (2,); the position correction clamped to the norm ``limit`` [m] (NaN: none)."""
    c0, c1 = kd[0] * e0, kd[1] * e1
    if limit == limit:
        n = math.sqrt(c0 * c0 + c1 * c1)
        if n > limit:
            c0, c1 = c0 * (limit / n), c1 * (limit / n)
    for k in range(3):
        out[0, k], out[1, k], out[2, k] = p[k], v[k], a[k]
    out[0, 0] -= c0
    out[0, 1] -= c1
    out[1, 0] -= kv[0] * e0 / dt
    out[1, 1] -= kv[1] * e1 / dt
    out[2, 0] -= ka[0] * e0 / dt**2
    out[2, 1] -= ka[1] * e1 / dt**2


@njit(exact=True)
def torso_roll(w_left, w_right, f_left, f_right, kd, kv, ka, limit, dt, R0, R, w, a):
    """Paper 004 Eq. 4-5 (`teleop.foot_force_difference` on the model's normal forces ``w_left[2]``,
    ``w_right[2]`` floored at 0 and the measured ones ``f_left``, ``f_right`` [N]) and the torso's reference from
    it: ``R`` (3, 3) = Rx(roll) ``R0``, ``w`` / ``a`` (6,) the roll rate and acceleration (angular x). The same
    operations as the numpy law, in the same order; ``limit`` NaN: none. Returns the roll [rad]."""
    ml = 0.0 if 0.0 > w_left[2] else w_left[2]   # Python's max(w, 0.0)
    mr = 0.0 if 0.0 > w_right[2] else w_right[2]
    D = (ml - mr) - (f_left - f_right)
    roll = -kd * D
    if limit == limit and abs(roll) > limit:
        roll = roll * (limit / abs(roll))
    c, s = math.cos(roll), math.sin(roll)
    for j in range(3):
        R[0, j] = R0[0, j]
        R[1, j] = c * R0[1, j] - s * R0[2, j]
        R[2, j] = s * R0[1, j] + c * R0[2, j]
    for j in range(6):
        w[j] = 0.0
        a[j] = 0.0
    w[3] = -kv * D / dt
    a[3] = -ka * D / (dt * dt)
    return roll


@njit
def ankle_admittance(R, c0, c1, kd_pitch, kd_roll, limit, out):
    """Paper 004 Eq. 3 (`teleop.ankle_admittance`): ``out`` (3, 3) = ``R`` tilted about its own axes by roll
    ``kd_roll c1`` and pitch ``-kd_pitch c0`` (the tilt clamped to the norm ``limit``, NaN: none; ``c`` the CoP in
    the sole frame from its centre [m]), ``R rpy(roll, pitch, 0)``; returns the tilt angle [rad]."""
    r, p = kd_roll * c1, -kd_pitch * c0
    if limit == limit:
        n = math.sqrt(r * r + p * p)
        if n > limit:
            r, p = r * (limit / n), p * (limit / n)
    cr, sr, cp, sp = math.cos(r), math.sin(r), math.cos(p), math.sin(p)
    # rpy(r, p, 0) = Ry(p) Rx(r)
    T = np.empty((3, 3))
    T[0, 0], T[0, 1], T[0, 2] = cp, sp * sr, sp * cr
    T[1, 0], T[1, 1], T[1, 2] = 0.0, cr, -sr
    T[2, 0], T[2, 1], T[2, 2] = -sp, cp * sr, cp * cr
    for i in range(3):
        for j in range(3):
            out[i, j] = R[i, 0] * T[0, j] + R[i, 1] * T[1, j] + R[i, 2] * T[2, j]
    s = 0.5 * math.sqrt((T[2, 1] - T[1, 2]) ** 2 + (T[0, 2] - T[2, 0]) ** 2 + (T[1, 0] - T[0, 1]) ** 2)
    return math.atan2(s, 0.5 * (T[0, 0] + T[1, 1] + T[2, 2] - 1.0))


@njit
def measure_feet(q, kinds, parents, idx_q, R0, t0, R_joints, t_joints, frame_parents, R_frames, t_frames, R_out, t_out,
                 f_left, f_right, m_left, m_right, f_sensor, m_sensor, foot_mass, foot_com, sole_center,
                 min_normal_force, gravity, out, zmp, alpha, state, started):
    """The stabilizer's measurement of a tick in one call: the placements of the sensor and sole frames for ``q``
    (`placements.joint_placements`, `frame_placements`; rows: left, right sensor, left, right sole into ``R_out``,
    ``t_out``), the F/T readings into ``f_sensor``, ``m_sensor`` (2, 3), `feet_measurement`, then
    `filter_measurement`; returns whether the ZMP exists."""
    joint_placements(q, kinds, parents, idx_q, R0, t0, R_joints, t_joints)
    frame_placements(R_joints, t_joints, frame_parents, R_frames, t_frames, R_out, t_out)
    for a in range(3):
        f_sensor[0, a], f_sensor[1, a] = f_left[a], f_right[a]
        m_sensor[0, a], m_sensor[1, a] = m_left[a], m_right[a]
    zmp_ok = feet_measurement(R_out[:2], t_out[:2], f_sensor, m_sensor, foot_mass, foot_com, R_out[2:], t_out[2:],
                              sole_center, min_normal_force, gravity, out, zmp)
    filter_measurement(out, zmp, zmp_ok, alpha, state, started)
    return zmp_ok


@njit(exact=True)
def corrections(state, loaded, measured_zmp, cop_R, cop_p, cop_w, cop_use, com_on, com_p, com_v, com_a, com_kd, com_kv,
                com_ka, com_limit, dt, com_out, torso_on, w_left, w_right, torso_kd, torso_kv, torso_ka, torso_limit,
                R0_torso, R_torso, w_torso, a_torso, ankle_on, R_nominal, kd_pitch, kd_roll, ankle_limit, R_tilt, log,
                flags):
    """The force-based stabilizer's corrections of a tick in one call, on its filtered measurement ``state`` (8,:
    `filter_measurement`), the feet's ``loaded`` flags (2,: `feet_measurement`'s ``out[:, 3]``) and whether the
    measurement gave a ZMP (``measured_zmp``):

    * ``log[:] = NaN``, then the measured ZMP (x y), the model's CoP (`model_cop` of ``cop_*``) into ``log[0:4]``;
    * Eq. 2 when ``com_on`` and both ZMPs exist: `com_admittance` of ``com_p``, ``com_v``, ``com_a`` into ``com_out``
      (3, 3), the correction into ``log[4:6]``;
    * Eq. 4-5 when ``torso_on``: `torso_roll` of the model's wrenches ``w_left``, ``w_right`` and the measured normal
      forces (``state[6:8]``) from ``R0_torso`` into ``R_torso``, ``w_torso``, ``a_torso``, the roll into ``log[6]``;
    * Eq. 3 for each foot i with ``ankle_on[i]``: `ankle_admittance` of ``R_nominal[i]`` into ``R_tilt[i]`` when the
      foot is loaded (its CoP ``state[2 + 2 i: 4 + 2 i]``), the tilt into ``log[7 + i]``.

    ``flags`` (int64, 5,) gets: the ZMP exists, Eq. 2 applied, Eq. 4-5 applied, then per foot 0 (not applied),
    1 (its nominal pose: unloaded), 2 (tilted). The same operations, in the same order, as the stabilizer's Python
    of those laws (its logs are compared bit for bit)."""
    for k in range(log.shape[0]):
        log[k] = np.nan
    zmp0 = state[0] if measured_zmp else np.nan
    zmp1 = state[1] if measured_zmp else np.nan
    zmp_ok = math.isfinite(zmp0 + zmp1)
    flags[0] = 1 if zmp_ok else 0
    log[0] = zmp0
    log[1] = zmp1
    cop = np.empty(2)
    cop_ok = model_cop(cop_R, cop_p, cop_w, cop_use, cop)
    if cop_ok:
        log[2] = cop[0]
        log[3] = cop[1]
    flags[1] = 0
    if com_on and cop_ok and zmp_ok:
        com_admittance(com_p, com_v, com_a, cop[0] - zmp0, cop[1] - zmp1, com_kd, com_kv, com_ka, com_limit, dt,
                       com_out)
        log[4] = com_out[0, 0] - com_p[0]
        log[5] = com_out[0, 1] - com_p[1]
        flags[1] = 1
    flags[2] = 0
    if torso_on:
        log[6] = torso_roll(w_left, w_right, state[6], state[7], torso_kd, torso_kv, torso_ka, torso_limit, dt,
                            R0_torso, R_torso, w_torso, a_torso)
        flags[2] = 1
    for i in range(2):
        flags[3 + i] = 0
        if ankle_on[i]:
            if loaded[i] != 0.0:
                log[7 + i] = ankle_admittance(R_nominal[i], state[2 + 2 * i], state[3 + 2 * i], kd_pitch, kd_roll,
                                              ankle_limit, R_tilt[i])
                flags[3 + i] = 2
            else:
                flags[3 + i] = 1
