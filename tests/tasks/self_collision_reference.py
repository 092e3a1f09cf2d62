"""A plain numpy reference of the self-collision task's position kernel (wbcbench/tasks/self_collision.py,
`_position_kernel`), for the tests only: the same quantities, written with numpy and pinocchio's joint Jacobians."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from wbcbench.tasks.self_collision import _LWA, _Cache, _cross, _joint_placements, _skew

FloatArray = np.ndarray


def reference_evaluate(self, model: pin.Model, data: pin.Data) -> tuple[_Cache, dict]:
    """The task's position cache (C, distances, Jacobian rows, the per-repulsor terms), computed with numpy and
    set as the task's; and per active repulsor (gradient, C coeff, C k d^(p-2), x - p, joint origin -> p)."""
    q = data.q_in
    key = (id(data), q.tobytes())
    R_all, t_all = _joint_placements(data, key, self._joints_needed)
    rx = R_all[0] @ self._offset_x
    x = t_all[0] + rx
    f = self._slot_of
    r = np.einsum("nij,nj->ni", R_all[f], self._rep_offsets_joint)  # joint origin -> point, world axes
    rel = x - t_all[f]
    rel -= r
    distances = np.sqrt(np.einsum("ni,ni->n", rel, rel))
    p = self._exponent
    C = np.exp(-(distances**p) / self._scales)
    n, nv = self.dim, model.nv
    J = np.zeros((n, nv))
    active = np.flatnonzero(C > self._negligible).tolist()
    rows = {}
    if active:
        Jx6 = pin.getJointJacobian(model, data, self._joint_x, _LWA)
        Jx = Jx6[:3] - _skew(rx) @ Jx6[3:]
        six: dict[int, FloatArray] = {}
        for i in active:
            rel_i, d, c = rel[i], float(distances[i]), float(C[i])
            k = p / float(self._scales[i])
            if d > 0.0:
                dp2 = d ** (p - 2.0)
                dp4 = d ** (p - 4.0) if p != 2.0 else 0.0
            else:
                dp2, dp4 = (1.0 if p == 2.0 else 0.0), 0.0
            g = (-k * dp2 * c) * rel_i
            # H = C (coeff rel rel^T - k d^(p-2) I), see attractor()
            coeff = k * k * dp2 * dp2 - (k * (p - 2.0) * dp4 if p != 2.0 else 0.0)
            Ji = g @ Jx
            j = self._rep_joint[i]
            if j != 0:  # 0: fixed in the world
                J6 = six.get(j)
                if J6 is None:
                    J6 = six[j] = pin.getJointJacobian(model, data, j, _LWA)
                Ji -= g @ J6[:3]
                Ji -= _cross(r[i], g) @ J6[3:]
            J[i] = Ji
            rows[i] = (g, c * coeff, c * k * dp2, rel_i, r[i])
    G, HC, HK, RW = np.zeros((n, 3)), np.zeros(n), np.zeros(n), np.zeros((n, 3))
    for i, (g, hc, hk, _, r_i) in rows.items():
        G[i], HC[i], HK[i], RW[i] = g, hc, hk, r_i
    self._cache = _Cache(key=key, C=C, distances=distances, J=J, active=active, rx=rx, x=x,
                         act=np.array(active, dtype=np.intp), G=G, HC=HC, HK=HK, REL=rel, RW=RW)
    return self._cache, rows


def reference_velocity(self, model: pin.Model, data: pin.Data) -> tuple[FloatArray, FloatArray]:
    """``C_dot = J v`` and the drift ``r_dot^T H r_dot + g^T (a_x - a_p)`` of the active repulsors, with
    pinocchio's joint velocities and classical accelerations and numpy (the velocity kernel's reference)."""
    cache, rows = reference_evaluate(self, model, data)
    v = data.v_in
    drift = np.zeros(self.dim)
    if cache.active:
        vx, ax = _point_motion(model, data, self._joint_x, cache.rx)
        for i in cache.active:
            g, hc, hk, rel_i, r_i = rows[i]
            vp, ap = _point_motion(model, data, self._rep_joint[i], r_i)
            rd = vx - vp
            # r_dot^T H r_dot with H = hc rel rel^T - hk I
            drift[i] = hc * float(rel_i @ rd) ** 2 - hk * float(rd @ rd) + float(g @ (ax - ap))
    return cache.J @ v, drift


def _point_motion(model: pin.Model, data: pin.Data, joint: int, r: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Velocity and classical acceleration at zero joint acceleration (3,) each, world axes, of the point at
    ``r`` (world axes) from the origin of ``joint``."""
    if joint == 0:
        return np.zeros(3), np.zeros(3)
    vel = pin.getVelocity(model, data, joint, _LWA)
    acc = pin.getClassicalAcceleration(model, data, joint, _LWA)
    w = vel.angular
    wr = _cross(w, r)
    return vel.linear + wr, acc.linear + _cross(acc.angular, r) + _cross(w, wr)

