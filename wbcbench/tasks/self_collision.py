"""Self-collision repulsor task (paper 004, Section IV, Eq. 8-13).

A point ``x`` of the robot (the tracked frame, e.g. the gripper, possibly at an offset) must stay away from
repulsion points ``p_i`` attached to other bodies (hips, torso, the other arm...). For each repulsor the
attractor function of Eq. 13,

    C_i(x) = exp(-||x - p_i||^p / s_i),      s_i = a_i = r_rep,i + r_frame        (paper, ``normalized=False``)
                                              s_i = a_i^p                          (``normalized=True``)

is driven to zero with the imposed dynamics of Eq. 8, ``C_ddot + Kd C_dot + Kp C = 0``. ``C`` is 1 on the
repulsion point and decays with the distance; the gradient points towards the repulsor, so the dynamics push
``x`` away. Eq. 13 as printed divides ``d^p`` by ``a`` (units m^p / m); the implementation in the authors'
inria_wbc used ``(d / a)^p``, for which ``a`` really is the radius of influence (C = 1/e at d = a and negligible
beyond 2a for p = 3). Both are offered; the default follows the paper's text.

The task space has one axis per repulsor (named after it), the task quantity being ``C_i(q)`` (dimensionless):

* error ``e_i = 0 - C_i`` (the reference is ``C* = 0`` with zero velocity and acceleration, fixed);
* jacobian ``J_i = grad C_i^T (J_x - J_p,i)`` (1, nv): ``J_x``, ``J_p,i`` are the world-axes linear Jacobians of
  the two points, so a repulsor that moves with the robot (hips, torso) is accounted for, not assumed fixed as in
  Eq. 10;
* velocity ``C_dot_i = J_i v``;
* drift ``J_dot_i v = r_dot^T H_i r_dot + grad C_i^T (a_x - a_p,i)``, ``r = x - p_i``, ``r_dot = (J_x - J_p,i) v``,
  ``a`` the classical point accelerations at zero joint acceleration (Eq. 10 with ``J_dot q_dot``).

With these, the generic acceleration rows of :func:`~wbcbench.tasks.acceleration_rows`,
``J dv = a_ref + Kd (v_ref - J v) + Kp e - J_dot v``, become ``grad C^T J dv = -Kd C_dot - Kp C - J_dot v``: exactly
Eq. 11-12 (``A = grad C^T J``, ``b = -(r_dot^T H r_dot + grad C^T (J_dot v) + Kd C_dot + Kp C)``), so the task
needs no special row computation. At velocity level the rows are ``C_dot = -Kp C``.

One row per repulsor (rather than the sum of all ``C_i`` in one row as inria_wbc does) keeps two repulsors on
either side of the gripper from cancelling each other. Table I of paper 004 uses one task per gripper with weight
700 and kp 500.

Barrier (optional, not in the paper): the same rows as hard inequalities of the QP, a second-order control
barrier on ``h_i = C_max,i - C_i`` (``h_ddot + kd_b h_dot + kp_b h >= 0``)::

    J_i dv <= -kd_b C_dot_i + kp_b (C_max,i - C_i) - J_dot_i v

with ``C_max,i`` the value of ``C_i`` at the distance ``clearance * a_i`` (``clearance`` 1: the protected sphere
touching the repulsion sphere). It is inactive while the point is far or slow (the bound is then large) and
brakes an approach in time wherever the weighted rows cannot: the soft rows act through ``grad C``, which is tiny
until the point is within about ``a`` of the repulsor, so a hand task pulling hard towards a reference across the
body (a hand that lagged behind a fast operator, or came back from out of reach) brings the gripper there at 2-3
m/s, too fast to stop (measured on public motion-capture recordings). :meth:`SelfCollisionTask.barrier_bounds`
gives the bounds from the task's stacked rows; the inverse-dynamics formulation adds them.
"""

from __future__ import annotations

import math
from collections import namedtuple
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.jit import njit
from wbcbench.tasks import _validation as val
from wbcbench.tasks.exceptions import TaskConfigError
from wbcbench.tasks.frame_batch import classical_acceleration, support_product
from wbcbench.tasks.placements import ForwardKinematics, _forward_gather
from wbcbench.tasks.task import Task

__all__ = ["RepulsionPoint", "SelfCollisionTask", "attractor"]

FloatArray = npt.NDArray[np.float64]
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

#: Default C below which a repulsor's row is left at zero (Jacobian and drift; the error keeps C): the point is
#: then farther than 2.1 a from the repulsor (p = 3, normalized), the row asks for |C_ddot| < kp C = 0.05 s^-2 with
#: Table I's kp 500, and |grad C| < 7e-3 per metre for a = 0.2 m (see SelfCollisionTask).
NEGLIGIBLE = 1e-4


def _skew(r: FloatArray) -> FloatArray:
    x, y, z = r
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a x b`` for (3,) vectors (np.cross costs ~20x more on one pair: it is called 50 times per tick)."""
    a0, a1, a2 = a
    b0, b1, b2 = b
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def attractor(r: npt.ArrayLike, exponent: float, scale: float) -> tuple[float, FloatArray, FloatArray]:
    """``C(r) = exp(-||r||^p / s)`` with its gradient and Hessian with respect to ``r`` (3,).

    With ``d = ||r||``, ``g = -(p / s) d^(p-2) C r`` and
    ``H = C [((p/s)^2 d^(2p-4) - (p/s)(p-2) d^(p-4)) r r^T - (p/s) d^(p-2) I]``, continuous for ``p >= 2``
    (at ``r = 0``: ``g = 0``, ``H = -(2/s) I`` for ``p = 2``, ``0`` for ``p > 2``).

    Args:
        r: the vector from the repulsion point to the point, (3,) [m].
        exponent: ``p`` >= 2.
        scale: ``s`` > 0, in m^p.

    Returns:
        ``(C, grad (3,), hessian (3, 3))``.
    """
    r = np.asarray(r, dtype=float)
    p, s = float(exponent), float(scale)
    d2 = float(r @ r)
    d = math.sqrt(d2)
    C = math.exp(-(d**p) / s)
    k = p / s
    if d == 0.0:
        H = -k * np.eye(3) if p == 2.0 else np.zeros((3, 3))
        return C, np.zeros(3), C * H
    dp2 = d ** (p - 2.0)
    g = -k * dp2 * C * r
    coeff = k * k * dp2 * dp2 - (k * (p - 2.0) * d ** (p - 4.0) if p != 2.0 else 0.0)
    H = C * (coeff * np.outer(r, r) - k * dp2 * np.eye(3))
    return C, g, H


RepulsorGeometry = namedtuple("RepulsorGeometry",
                              ["slot_of", "offsets", "offset_x", "scales", "exponent", "negligible", "masks",
                               "mask_x"])
RepulsorGeometry.__doc__ = """A self-collision task's fixed inputs to :func:`_position_kernel`: ``slot_of`` (n,) the
row of each repulsor's joint in the placements, ``offsets`` (n, 3) each repulsor in its joint's frame [m],
``offset_x`` (3,) the protected point in its joint's frame (slot 0) [m], ``scales`` (n,) ``s_i``, ``exponent``
``p``, ``negligible`` the value of ``C`` below which a repulsor gives no row, ``masks`` (n, nv) / ``mask_x`` (nv,)
the supports (velocity columns) of the repulsors' joints / of the protected point's joint."""

PositionOutputs = namedtuple("PositionOutputs", ["C", "dist", "J", "G", "HC", "HK", "REL", "RW", "rx", "act"])
PositionOutputs.__doc__ = """The buffers :func:`_position_kernel` fills: ``C`` (n,), ``dist`` (n,) [m], the rows
``J`` (n, nv); for the active repulsors (indices in ``act``) the gradient ``G`` (n, 3), the Hessian coefficients
``HC`` (of rel rel^T) and ``HK`` (of I) (n,), ``REL = x - p_i`` (n, 3); ``RW`` (n, 3) joint origin -> point and
``rx`` (3,) for the protected point, world axes [m]."""


def _position_kernel(R_all, t_all, JW, geo, out):
    """The compiled position-level quantities of ``SelfCollisionTask._evaluate``: ``R_all`` (k, 3, 3), ``t_all``
    (k, 3) the placements of the joints carrying the points (slot 0: the protected point's), ``JW`` pinocchio's
    ``data.J`` (WORLD: point velocity ``J_lin - skew(point) J_ang`` on the columns of the joint's support),
    ``geo`` a :class:`RepulsorGeometry`; fills ``out`` (:class:`PositionOutputs`; ``J`` zero for the negligible
    repulsors) and returns the number of active repulsors (their indices first in ``out.act``)."""
    return _position_flat(R_all, t_all, JW, *geo, *out)


# flat arrays: numba types a named tuple argument in Python on every call (~2-4 us, measured), flat arrays in C
@njit
def _position_flat(R_all, t_all, JW, slot_of, offsets, offset_x, scales, p, negligible, masks, mask_x, C, dist, J, G,
                   HC, HK, REL, RW, rx, act):
    """`_position_kernel` on flat arrays."""
    n = slot_of.shape[0]
    nv = JW.shape[1]
    for a in range(3):
        rx[a] = R_all[0, a, 0] * offset_x[0] + R_all[0, a, 1] * offset_x[1] + R_all[0, a, 2] * offset_x[2]
    x0 = t_all[0, 0] + rx[0]
    x1 = t_all[0, 1] + rx[1]
    x2 = t_all[0, 2] + rx[2]
    nact = 0
    for i in range(n):
        s = slot_of[i]
        for a in range(3):
            RW[i, a] = R_all[s, a, 0] * offsets[i, 0] + R_all[s, a, 1] * offsets[i, 1] + R_all[s, a, 2] * offsets[i, 2]
        p0 = t_all[s, 0] + RW[i, 0]
        p1 = t_all[s, 1] + RW[i, 1]
        p2 = t_all[s, 2] + RW[i, 2]
        e0, e1, e2 = x0 - p0, x1 - p1, x2 - p2
        REL[i, 0], REL[i, 1], REL[i, 2] = e0, e1, e2
        d = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        dist[i] = d
        c = np.exp(-(d ** p) / scales[i])
        C[i] = c
        for col in range(nv):
            J[i, col] = 0.0
        if not c > negligible:
            continue
        act[nact] = i
        nact += 1
        k = p / scales[i]
        if d > 0.0:
            dp2 = d ** (p - 2.0)
            dp4 = d ** (p - 4.0) if p != 2.0 else 0.0
        else:
            dp2 = 1.0 if p == 2.0 else 0.0
            dp4 = 0.0
        f = -k * dp2 * c
        g0, g1, g2 = f * e0, f * e1, f * e2
        G[i, 0], G[i, 1], G[i, 2] = g0, g1, g2
        coeff = k * k * dp2 * dp2 - (k * (p - 2.0) * dp4 if p != 2.0 else 0.0)
        HC[i] = c * coeff
        HK[i] = c * k * dp2
        # g^T skew(a) w = (g x a) . w
        gx0, gx1, gx2 = g1 * x2 - g2 * x1, g2 * x0 - g0 * x2, g0 * x1 - g1 * x0
        gp0, gp1, gp2 = g1 * p2 - g2 * p1, g2 * p0 - g0 * p2, g0 * p1 - g1 * p0
        for col in range(nv):
            jl = g0 * JW[0, col] + g1 * JW[1, col] + g2 * JW[2, col]
            v = 0.0
            if mask_x[col]:
                v += jl - (gx0 * JW[3, col] + gx1 * JW[4, col] + gx2 * JW[5, col])
            if masks[i, col]:
                v -= jl - (gp0 * JW[3, col] + gp1 * JW[4, col] + gp2 * JW[5, col])
            J[i, col] = v
    return nact


VelocityInputs = namedtuple("VelocityInputs", ["x", "rx", "act", "slot_of", "G", "HC", "HK", "REL", "RW", "ACC",
                                               "mask_x", "masks"])
VelocityInputs.__doc__ = """The inputs of :func:`_velocity_kernel` besides pinocchio's ``data.J`` and ``v``: the protected
point ``x`` and ``rx`` (its joint origin -> it) (3,), world [m]; the active repulsors ``act``; the position kernel's
``slot_of``, ``G``, ``HC``, ``HK``, ``REL``, ``RW`` (:class:`PositionOutputs`); ``ACC`` (k, 6) the classical
accelerations at zero joint acceleration of the joints' origins (linear, angular; world axes) per slot, read for
slot 0 and the active repulsors' slots (zero for a point fixed in the world); ``mask_x`` / ``masks`` the supports
(:class:`RepulsorGeometry`)."""


def _velocity_kernel(JW, v, J, inp, velocity, drift):
    """The compiled velocity-level quantities of ``SelfCollisionTask._evaluate_velocity``: ``velocity = J v``
    (n,) and, for the active repulsors, ``drift_i = r_dot^T H_i r_dot + g_i^T (a_x - a_p,i)`` (the others 0),
    with the point velocities from the world Jacobians ``JW`` (``v_X = J_lin v + w x X`` on the support of the
    point's joint, ``w = J_ang v``) and the point accelerations ``a = a_origin + alpha x r + w x (w x r)``
    (``inp``: :class:`VelocityInputs`)."""
    _velocity_flat(JW, v, J, *inp, velocity, drift)


@njit
def _point_velocity(JW, v, mask, X):
    """Velocity (3,) of the world point ``X`` moving with the joint of support ``mask``, and that joint's angular
    velocity (3,), world axes."""
    vo = support_product(JW, v, mask)  # (v_o, w) at the world origin
    lin, w = vo[:3].copy(), vo[3:].copy()
    lin[0] += w[1] * X[2] - w[2] * X[1]
    lin[1] += w[2] * X[0] - w[0] * X[2]
    lin[2] += w[0] * X[1] - w[1] * X[0]
    return lin, w


@njit
def _point_acceleration(acc, w, r):
    """Classical acceleration (3,) of the point at ``r`` from a joint origin of classical acceleration ``acc``
    (6,: linear at the origin, angular) and angular velocity ``w``: ``a + alpha x r + w x (w x r)``."""
    wr0, wr1, wr2 = w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2], w[0] * r[1] - w[1] * r[0]
    out = np.empty(3)
    out[0] = acc[0] + (acc[4] * r[2] - acc[5] * r[1]) + (w[1] * wr2 - w[2] * wr1)
    out[1] = acc[1] + (acc[5] * r[0] - acc[3] * r[2]) + (w[2] * wr0 - w[0] * wr2)
    out[2] = acc[2] + (acc[3] * r[1] - acc[4] * r[0]) + (w[0] * wr1 - w[1] * wr0)
    return out


@njit
def _velocity_flat(JW, v, J, x, rx, act, slot_of, G, HC, HK, REL, RW, ACC, mask_x, masks, velocity, drift):
    """`_velocity_kernel` on flat arrays."""
    n, nv = J.shape
    for i in range(n):
        s = 0.0
        for col in range(nv):
            s += J[i, col] * v[col]
        velocity[i] = s
        drift[i] = 0.0
    if act.shape[0] == 0:
        return
    vx, wx = _point_velocity(JW, v, mask_x, x)
    ax = _point_acceleration(ACC[0], wx, rx)
    P = np.empty(3)
    for i in act:
        for a in range(3):
            P[a] = x[a] - REL[i, a]
        vp, wp = _point_velocity(JW, v, masks[i], P)
        ap = _point_acceleration(ACC[slot_of[i]], wp, RW[i])
        rd0, rd1, rd2 = vx[0] - vp[0], vx[1] - vp[1], vx[2] - vp[2]
        # r_dot^T H r_dot with H = hc rel rel^T - hk I
        proj = REL[i, 0] * rd0 + REL[i, 1] * rd1 + REL[i, 2] * rd2
        drift[i] = (HC[i] * proj * proj - HK[i] * (rd0 * rd0 + rd1 * rd1 + rd2 * rd2)
                    + G[i, 0] * (ax[0] - ap[0]) + G[i, 1] * (ax[1] - ap[1]) + G[i, 2] * (ax[2] - ap[2]))


@njit
def _joint_accelerations(JW, dJ, v, masks, origins, acc):
    """Classical accelerations at zero joint acceleration (6,: linear of the joint origin, angular; world axes)
    of the joints of support ``masks`` (k, nv) and origins ``origins`` (k, 3) into ``acc`` (k, 6)
    (`frame_batch.classical_acceleration`; the universe, an empty support, gives 0)."""
    for k in range(masks.shape[0]):
        classical_acceleration(JW, dJ, v, masks[k], origins[k], acc[k])


@njit
def _velocity_and_drift(JW, dJ, v, slot_masks, origins, acc, J, x, rx, act, slot_of, G, HC, HK, REL, RW, mask_x,
                        masks, velocity, drift):
    """`_joint_accelerations` of the slots `_velocity_flat` reads (the protected point's and the active
    repulsors'; the others' rows of ``acc`` are left as they are), then `_velocity_flat` (one call)."""
    if act.shape[0]:
        done = np.zeros(slot_masks.shape[0], dtype=np.bool_)
        classical_acceleration(JW, dJ, v, slot_masks[0], origins[0], acc[0])
        done[0] = True
        for i in act:
            s = slot_of[i]
            if not done[s]:
                classical_acceleration(JW, dJ, v, slot_masks[s], origins[s], acc[s])
                done[s] = True
    _velocity_flat(JW, v, J, x, rx, act, slot_of, G, HC, HK, REL, RW, acc, mask_x, masks, velocity, drift)


@njit
def _rows_flat(q, kinds, parents, idx_q, R0, t0, R_fk, t_fk, joints, R_all, t_all, JW, dJ, v, slot_of, offsets,
               offset_x, scales, p, negligible, masks, mask_x, C, dist, J, G, HC, HK, REL, RW, rx, act, slot_masks, acc,
               x, velocity, drift, with_velocity):
    """A tick's evaluation in one call: the joints' placements (`placements._forward_gather`), the position-level
    quantities (`_position_flat`), the protected point ``x``, and with ``with_velocity`` the velocities and drifts
    (`_velocity_and_drift`); returns the number of active repulsors."""
    _forward_gather(q, kinds, parents, idx_q, R0, t0, R_fk, t_fk, joints, R_all, t_all)
    nact = _position_flat(R_all, t_all, JW, slot_of, offsets, offset_x, scales, p, negligible, masks, mask_x, C, dist,
                          J, G, HC, HK, REL, RW, rx, act)
    for a in range(3):
        x[a] = t_all[0, a] + rx[a]
    if with_velocity:
        _velocity_and_drift(JW, dJ, v, slot_masks, t_all, acc, J, x, rx, act[:nact], slot_of, G, HC, HK, REL, RW,
                            mask_x, masks, velocity, drift)
    return nact


@njit(exact=True)
def _barrier_rows(A, b, cdot, C, cmax, kp, kd, kd_b, kp_b, rows_out, copy_rows, out):
    """`SelfCollisionTask.barrier_rows`: ``out = (Kd - kd_b) C_dot + b + Kp C + kp_b (C_max - C)`` per row (``cdot``
    = A v, the task's gains ``kp``, ``kd`` per row; numpy's operations, in its order), and ``rows_out = A`` when
    ``copy_rows``."""
    for i in range(A.shape[0]):
        if copy_rows:
            for j in range(A.shape[1]):
                rows_out[i, j] = A[i, j]
        out[i] = (kd[i] - kd_b) * cdot[i] + b[i] + kp[i] * C[i] + kp_b * (cmax[i] - C[i])


_NO_ROWS = np.zeros((0, 0))
_PLACEMENTS: dict = {"key": None, "joints": {}}
_NO_VECTOR = np.zeros(0)


def _joint_placements(data: pin.Data, key: tuple, joints: tuple[int, ...]) -> tuple[FloatArray, FloatArray]:
    """Rotations (k, 3, 3) and translations (k, 3) of ``data.oMi[j]`` for ``joints``; each joint is read once
    per configuration ``key`` whichever task asks (the left and right grippers' tasks share most repulsors)."""
    if _PLACEMENTS["key"] != key:
        _PLACEMENTS["key"] = key
        _PLACEMENTS["joints"] = {}
    known = _PLACEMENTS["joints"]
    R = np.empty((len(joints), 3, 3))
    t = np.empty((len(joints), 3))
    oMi = data.oMi
    for k, j in enumerate(joints):
        c = known.get(j)
        if c is None:
            M = oMi[j]
            c = known[j] = (M.rotation, M.translation)
        R[k], t[k] = c
    return R, t


@dataclass(frozen=True)
class RepulsionPoint:
    """A repulsion point attached to a robot frame.

    Attributes:
        frame: the frame that carries it (``"universe"`` for a point fixed in the world).
        radius: ``r_rep`` [m], >= 0.
        offset: position in ``frame`` [m] (3,).
        name: the task axis name; default the frame name (with ``#k`` appended when the frame carries several).
    """

    frame: str
    radius: float
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    name: str | None = None


@dataclass
class _Cache:
    """One configuration's quantities (``key``: data and q; ``vkey``: v), the arrays those of the kernels
    (:class:`PositionOutputs`, ``x`` the protected point, ``act`` the active repulsors' indices); None before the
    first evaluation."""

    key: tuple[int, bytes] | None = None
    vkey: bytes | None = None
    C: FloatArray | None = None
    distances: FloatArray | None = None
    J: FloatArray | None = None
    active: list | None = None     # repulsors with C > negligible
    rx: FloatArray | None = None
    x: FloatArray | None = None
    act: npt.NDArray[np.intp] | None = None
    G: FloatArray | None = None
    HC: FloatArray | None = None
    HK: FloatArray | None = None
    REL: FloatArray | None = None
    RW: FloatArray | None = None
    velocity: FloatArray | None = None
    drift: FloatArray | None = None
    origins: FloatArray | None = None  # (k, 3) origins of the joints carrying the points (slots), world


class SelfCollisionTask(Task):
    """Keep a point of frame ``frame`` away from repulsion points (see the module docstring).

    Args:
        model: robot model (frames resolved at construction).
        frame: frame carrying the protected point, e.g. ``"gripper_left_base_link"``.
        repulsors: the repulsion points (at least one).
        radius: ``r_frame`` [m], >= 0, the radius around the protected point.
        offset: the protected point in ``frame`` [m] (3,).
        exponent: ``p`` >= 2 (the Hessian must exist everywhere).
        normalized: False: ``C = exp(-d^p / a)`` (paper Eq. 13); True: ``C = exp(-(d / a)^p)`` (inria_wbc).
        negligible: a repulsor whose ``C`` is at or below this gets a zero Jacobian row and drift (its error
            stays ``-C``): it costs no pinocchio query and no row arithmetic. Default ``NEGLIGIBLE``; 0 gives the
            exact rows of every repulsor.
        kp: 1/s^2, scalar or one per repulsor (Table I: 500).
        kd: 1/s; default ``2 sqrt(kp)``.
        weight: QP weight (Table I: 700).
        mask: one entry per repulsor.
        name: task name, default ``"self_collision-<frame>"``.
        barrier: ``None`` (default: soft rows only) or ``(clearance, kp_b, kd_b)``: the rows are also hard
            inequalities keeping every repulsor's ``C`` below its value at ``clearance * a_i`` (module docstring).

    Raises:
        UnknownNameError: unknown frame (the message lists close names).
        TaskConfigError: no repulsor, negative radius, ``r_rep + r_frame = 0``, ``p < 2``, duplicate axis name,
            invalid gain, mask, weight or barrier.
    """

    yaml_type = "self_collision"

    @classmethod
    def parse_options(cls, sec: Any, robot: Any) -> dict:
        """`side: left|right` picks the robot profile's `repulsors` set of that side (protected point, its frame,
        exponent, the repulsion points and their radii); one axis per repulsion point. `barrier: {clearance, kp,
        kd}` (optional; clearance default 1, kd default 2 sqrt(kp)) adds the hard barrier rows."""
        from wbcbench.side import Side

        side = Side(sec.str("side", choices=[s.value for s in Side]))
        repulsors = robot.profile.repulsors.get(side)
        if repulsors is None:
            raise sec.error("side", f"the robot profile {robot.profile.file} has no `repulsors.{side.value}` "
                                    "section (the repulsion points of a self_collision task come from the profile)")
        barrier = None
        if sec.has("barrier"):
            b = sec.section("barrier")
            kp_b = b.float("kp", positive=True)
            barrier = (b.float("clearance", 1.0, positive=True), kp_b, b.float("kd", 2.0 * math.sqrt(kp_b), min=0.0))
        return {"side": side, "repulsors": repulsors, "barrier": barrier}

    @classmethod
    def axes(cls, robot: Any, options: dict) -> int:
        return len(options["repulsors"].points)

    @classmethod
    def from_spec(cls, robot: Any, spec: Any) -> SelfCollisionTask:
        rep = spec.options["repulsors"]
        points = [RepulsionPoint(p.frame, p.radius, p.offset, p.name) for p in rep.points]
        return cls(robot.model, rep.frame, points, radius=rep.radius, offset=rep.offset, exponent=rep.exponent,
                   normalized=rep.normalized, kp=spec.kp, kd=spec.kd, weight=spec.weight, mask=spec.mask,
                   name=spec.name, barrier=spec.options.get("barrier"))

    def __init__(
        self,
        model: pin.Model,
        frame: str,
        repulsors: Sequence[RepulsionPoint],
        *,
        radius: float,
        kp: Any,
        kd: Any = None,
        offset: npt.ArrayLike = (0.0, 0.0, 0.0),
        exponent: float = 3.0,
        normalized: bool = False,
        negligible: float = NEGLIGIBLE,
        weight: float = 1.0,
        mask: Sequence[bool | int] | None = None,
        name: str | None = None,
        barrier: tuple[float, float, float] | None = None,
    ) -> None:
        task_name = f"self_collision-{frame}" if name is None else name
        owner = f"{type(self).__name__} {task_name!r}"
        self._frame_id = val.find_frame(model, frame, owner)
        self._frame = frame
        self._offset = val.frozen(val.as_vector(offset, 3, owner, "offset"))
        self._radius = val.as_scalar(radius, owner, "radius")
        self._exponent = val.as_scalar(exponent, owner, "exponent", minimum=2.0)
        self._normalized = bool(normalized)
        self._negligible = val.as_scalar(negligible, owner, "negligible")
        if isinstance(repulsors, RepulsionPoint) or not len(repulsors):
            raise TaskConfigError(owner, "repulsors", "expected a non-empty sequence of RepulsionPoint")
        counts: dict[str, int] = {}
        for rep in repulsors:
            counts[rep.frame] = counts.get(rep.frame, 0) + 1
        seen: dict[str, int] = {}
        axis_names, ids, offsets, radii = [], [], [], []
        for k, rep in enumerate(repulsors):
            if not isinstance(rep, RepulsionPoint):
                raise TaskConfigError(owner, f"repulsors[{k}]", f"expected a RepulsionPoint, got {type(rep).__name__}")
            key = f"repulsors[{k}]"
            ids.append(val.find_frame(model, rep.frame, owner, f"{key}.frame"))
            offsets.append(val.as_vector(rep.offset, 3, owner, f"{key}.offset"))
            radii.append(val.as_scalar(rep.radius, owner, f"{key}.radius"))
            label = rep.name
            if label is None:
                seen[rep.frame] = seen.get(rep.frame, 0) + 1
                label = rep.frame if counts[rep.frame] == 1 else f"{rep.frame}#{seen[rep.frame]}"
            if label in axis_names:
                raise TaskConfigError(owner, f"{key}.name", f"axis name {label!r} is used twice")
            axis_names.append(label)
        self._rep_ids = tuple(ids)
        self._rep_offsets = val.frozen(np.array(offsets))
        # every point from its parent joint: joint id and the point in the joint frame
        self._joint_x = int(model.frames[self._frame_id].parentJoint)
        self._offset_x = val.frozen(np.array(model.frames[self._frame_id].placement.act(self._offset)))
        self._rep_joint = tuple(int(model.frames[fid].parentJoint) for fid in ids)
        self._rep_offsets_joint = val.frozen(np.array([model.frames[fid].placement.act(np.asarray(off, float))
                                                       for fid, off in zip(ids, offsets)]))
        self._joints_needed = tuple(dict.fromkeys((self._joint_x, *self._rep_joint)))  # the protected point's first
        self._slot_of = np.array([self._joints_needed.index(j) for j in self._rep_joint], dtype=np.intp)
        self._rep_radii = val.frozen(np.array(radii))
        a = self._rep_radii + self._radius
        if np.any(a <= 0.0):
            raise TaskConfigError(owner, "radius", "r_rep + r_frame must be > 0 for every repulsor")
        self._a = val.frozen(a)
        self._scales = val.frozen(a**self._exponent if self._normalized else a.copy())
        super().__init__(
            name=task_name, axis_names=axis_names, units=("1",) * len(axis_names), weight=weight, kp=kp, kd=kd,
            mask=mask,
        )
        self._cache = _Cache()
        # the compiled kernel's inputs: supports of the joints carrying the points, work buffers

        def support(joint: int) -> npt.NDArray[np.bool_]:
            mask = np.zeros(model.nv, dtype=bool)
            if joint > 0:
                for j in model.supports[joint]:
                    if j > 0:
                        jm = model.joints[j]
                        mask[jm.idx_v:jm.idx_v + jm.nv] = True
            return mask

        self._mask_x = support(self._joint_x)
        self._masks = np.array([support(j) for j in self._rep_joint])
        self._slot_masks = np.array([support(j) for j in self._joints_needed])
        self._act = np.zeros(self.dim, dtype=np.intp)
        self._acc = np.zeros((len(self._joints_needed), 6))
        self._outputs: PositionOutputs | None = None
        self._rows_args: tuple | None = None
        self._velocity_out = (np.empty(self.dim), np.empty(self.dim))
        self._fk = ForwardKinematics(model)
        self._joints_index = np.array(self._joints_needed, dtype=np.intp)
        self._placements = (np.empty((len(self._joints_needed), 3, 3)), np.empty((len(self._joints_needed), 3)))
        self._geometry = RepulsorGeometry(self._slot_of, self._rep_offsets_joint, self._offset_x, self._scales,
                                          float(self._exponent), float(self._negligible), self._masks, self._mask_x)
        self.barrier = None
        if barrier is not None:
            if len(barrier) != 3 or not all(np.isfinite(x) for x in barrier) or barrier[0] <= 0 or barrier[1] <= 0 \
                    or barrier[2] < 0:
                raise TaskConfigError(owner, "barrier", f"expected (clearance > 0, kp > 0, kd >= 0), got {barrier!r}")
            self.barrier = tuple(float(x) for x in barrier)
            # C at the distance clearance * a_i, per repulsor
            self._barrier_cmax = val.frozen(np.exp(-((self.barrier[0] * a) ** self._exponent) / self._scales))
        self._barrier_idle = False  # `barrier_rows` zeroed the rows of its last call (no repulsor active)

    # ------------------------------------------------------------------------------------------ description
    @property
    def frame(self) -> str:
        """Frame carrying the protected point."""
        return self._frame

    @property
    def influence_radii(self) -> FloatArray:
        """``a_i = r_rep,i + r_frame`` per repulsor [m], read-only."""
        return self._a

    @property
    def scales(self) -> FloatArray:
        """The denominators ``s_i`` of the exponent (``a_i`` or ``a_i^p``), read-only."""
        return self._scales

    @property
    def exponent(self) -> float:
        """``p``."""
        return self._exponent

    def set_reference_to_current(self, model: pin.Model, data: pin.Data) -> None:
        """No-op: the reference is fixed (``C* = 0`` with zero velocity and acceleration). Present so that a
        controller can reset every task the same way."""

    # -------------------------------------------------------------------------------------------- points
    def _evaluate(self, model: pin.Model, data: pin.Data) -> _Cache:
        """Position-level quantities, cached per (data, q).

        Every point is placed from its parent joint's placement (computed from ``q`` by the compiled
        `ForwardKinematics`, the same as pinocchio's ``data.oMi``; for other joint types ``data.oMi``, read once
        per configuration for every task, ``_joint_placements``); ``C`` is computed for every repulsor, the gradient and the
        Jacobian row only for those whose ``C`` exceeds ``negligible`` (pinocchio's joint Jacobians, once per
        joint); the others' rows are zero (see ``NEGLIGIBLE``): usually every repulsor but one or two is that
        far. Per active repulsor, with ``r`` the vector from its joint's origin to it (world axes) and ``J6``
        that joint's world-axes Jacobian, ``J_i = g^T J_x - g^T J6_lin - (r x g)^T J6_ang`` (the gradient
        ``g`` applied to ``J_x - J_p``, ``J_p = J6_lin - skew(r) J6_ang``)."""
        q = data.q_in
        key = (id(data), q.tobytes())
        cache = self._cache
        if cache.key == key:
            return cache
        fk = self._fk
        if fk.supported and fk.model is model:
            R_all, t_all = self._placements
            fk.joints(q, self._joints_index, R_all, t_all)
        else:
            R_all, t_all = _joint_placements(data, key, self._joints_needed)
        return self._evaluate_jit(model, data, key, R_all, t_all)

    def _evaluate_jit(self, model: pin.Model, data: pin.Data, key: tuple, R_all: FloatArray,
                      t_all: FloatArray) -> _Cache:
        """The position-level quantities of :meth:`_evaluate` from the compiled kernel (``_position_kernel``); a
        numpy reference of the same is in the tests (tests/tasks/self_collision_reference.py). The kernel's
        buffers are the task's own, overwritten at the next configuration (the cache holds one configuration;
        the public methods return copies)."""
        out = self._position_outputs(model)
        k = _position_kernel(R_all, t_all, data.J, self._geometry, out)
        return self._new_cache(key, out, k, t_all[0] + out.rx, t_all)

    def _position_outputs(self, model: pin.Model) -> PositionOutputs:
        """The position kernel's buffers (allocated for the model's nv, kept between ticks)."""
        out = self._outputs
        if out is None or out.J.shape[1] != model.nv:
            n, nv = self.dim, model.nv
            out = self._outputs = PositionOutputs(np.empty(n), np.empty(n), np.empty((n, nv)), np.empty((n, 3)),
                                                  np.empty(n), np.empty(n), np.empty((n, 3)), np.empty((n, 3)),
                                                  np.empty(3), self._act)
            self._rows_args = None  # they hold the old buffers
        return out

    def _new_cache(self, key: tuple, out: PositionOutputs, k: int, x: FloatArray, origins: FloatArray) -> _Cache:
        """The cache of a configuration from the position kernel's outputs (``k`` active repulsors first in
        ``out.act``), the protected point ``x`` and the joints' origins."""
        idx = out.act[:k].copy()
        c = self._cache  # refilled: it holds one configuration, its arrays the kernels' own
        c.key, c.vkey, c.C, c.distances, c.J, c.active, c.rx, c.x, c.act = (key, None, out.C, out.dist, out.J,
                                                                             idx.tolist(), out.rx, x, idx)
        c.G, c.HC, c.HK, c.REL, c.RW, c.velocity, c.drift, c.origins = (out.G, out.HC, out.HK, out.REL, out.RW, None,
                                                                         None, origins)
        return c

    def _evaluate_velocity(self, model: pin.Model, data: pin.Data) -> _Cache:
        """``C_dot = J v``; drift ``r_dot^T H r_dot + g^T (a_x - a_p)`` for the active repulsors (``r_dot`` the
        relative point velocity, ``a`` classical point accelerations at zero joint acceleration), 0 for the
        others: the compiled ``_velocity_kernel``, given the classical accelerations of the joints carrying the
        protected point and the active repulsors (a numpy reference is in the tests)."""
        cache = self._evaluate(model, data)
        v = data.v_in
        vkey = v.tobytes()
        if cache.vkey == vkey:
            return cache
        acc = self._acc
        velocity, drift = self._velocity_out
        if cache.active and cache.origins is not None:
            # the joints' classical accelerations (pinocchio's getClassicalAcceleration, LOCAL_WORLD_ALIGNED) from
            # the world Jacobians and their time variation, with the velocities (flat arguments: one call)
            _velocity_and_drift(data.J, data.dJ, v, self._slot_masks, cache.origins, acc, cache.J, cache.x,
                                cache.rx, cache.act, self._slot_of, cache.G, cache.HC, cache.HK, cache.REL, cache.RW,
                                self._mask_x, self._masks, velocity, drift)
        else:
            if cache.active:  # a cache without the joint origins (set from outside the kernel): pinocchio's
                joints = self._joints_needed
                for slot in {0, *self._slot_of[cache.act].tolist()}:
                    j = joints[slot]
                    acc[slot] = 0.0 if j == 0 else pin.getClassicalAcceleration(model, data, j, _LWA).vector
            _velocity_flat(data.J, v, cache.J, cache.x, cache.rx, cache.act, self._slot_of, cache.G, cache.HC,
                           cache.HK, cache.REL, cache.RW, acc, self._mask_x, self._masks, velocity, drift)
        cache.velocity = velocity
        cache.drift = drift
        cache.vkey = vkey
        return cache

    def _write_rows(self, model: pin.Model, data: pin.Data, J_out: FloatArray, e_out: FloatArray,
                    drift_out: FloatArray | None) -> None:
        """The stack's evaluation (see `Task._write_rows`): placements, rows, velocities and drifts in one compiled
        call (`_rows_flat`), the same quantities as `_evaluate` and `_evaluate_velocity`, whose cache it sets."""
        fk = self._fk
        if not (fk.supported and fk.model is model):
            super()._write_rows(model, data, J_out, e_out, drift_out)
            return
        q = data.q_in
        key = (id(data), q.tobytes())
        cache = self._cache
        if cache.key != key or (drift_out is not None and cache.vkey is None):
            out = self._position_outputs(model)
            args = self._rows_args
            if args is None:  # the kernel's fixed arguments, in its order around q, the Jacobians and v
                g = self._geometry
                args = self._rows_args = (
                    (fk._kinds, fk._parents, fk._idx_q, fk._R0, fk._t0, fk.R, fk.t, self._joints_index,
                     *self._placements),
                    (g.slot_of, g.offsets, g.offset_x, g.scales, g.exponent, g.negligible, g.masks, g.mask_x, *out,
                     self._slot_masks, self._acc))
            with_velocity = drift_out is not None
            v = data.v_in if with_velocity else _NO_VECTOR
            x = np.empty(3)
            velocity, drift = self._velocity_out
            JW = data.J
            k = _rows_flat(q, *args[0], JW, data.dJ if with_velocity else JW, v, *args[1], x, velocity, drift,
                           with_velocity)
            cache = self._new_cache(key, out, k, x, self._placements[1])
            if with_velocity:
                cache.velocity, cache.drift, cache.vkey = velocity, drift, v.tobytes()
        elif drift_out is not None:
            cache = self._evaluate_velocity(model, data)
        sel = None if self._all_selected else self._selection
        J_out[...] = cache.J if sel is None else cache.J[sel]
        np.negative(cache.C if sel is None else cache.C[sel], out=e_out)
        if drift_out is not None:
            drift_out[...] = cache.drift if sel is None else cache.drift[sel]

    def _write_jacobian(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        J = self._evaluate(model, data).J
        out[...] = J if self._all_selected else J[self._selection]

    def _write_error(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        C = self._evaluate(model, data).C
        if self._all_selected:
            np.negative(C, out=out)
        else:
            out[...] = -C[self._selection]

    def _write_drift(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        a = self._evaluate_velocity(model, data).drift
        out[...] = a if self._all_selected else a[self._selection]

    def barrier_bounds(self, model: pin.Model, data: pin.Data, A: FloatArray, b: FloatArray,
                       v: FloatArray, out: FloatArray) -> None:
        """Upper bounds ``u`` of the barrier rows ``A dv <= u`` (module docstring) from the task's own stacked
        acceleration rows ``A`` (dim, nv), ``b`` (dim,) (``b = -Kd C_dot - Kp C - J_dot v``, the reference
        being fixed at 0) at velocity ``v``: ``u = b + (Kd - kd_b) C_dot + Kp C + kp_b (C_max - C)``, into
        ``out`` (dim,). Only for a task built with a ``barrier``."""
        self.barrier_rows(model, data, A, b, v, None, out)

    def barrier_rows(self, model: pin.Model, data: pin.Data, A: FloatArray, b: FloatArray, v: FloatArray,
                     rows_out: FloatArray | None, out: FloatArray) -> None:
        """`barrier_bounds` into ``out``, and the rows ``A`` copied into ``rows_out`` (dim, nv) when given, in one
        compiled call (the inverse-dynamics formulation's per-tick use)."""
        _, kp_b, kd_b = self.barrier
        cache = self._evaluate(model, data)
        cmax = self._barrier_cmax if self._all_selected else self._barrier_cmax[self._selection]
        if not cache.active and rows_out is not None:
            # no repulsor active: every row and value is zero, the bounds kp_b C_max (the same numbers); the rows are
            # zeroed once when the last repulsor leaves
            if not self._barrier_idle:
                rows_out[...] = 0.0
                self._barrier_idle = True
            np.multiply(cmax, kp_b, out=out)
            return
        self._barrier_idle = False
        C, kp, kd = cache.C, self._kp, self._kd
        if not self._all_selected:
            sel = self._selection
            C, kp, kd = C[sel], kp[sel], kd[sel]
        _barrier_rows(A, b, A @ v, C, cmax, kp, kd, float(kd_b), float(kp_b),
                      _NO_ROWS if rows_out is None else rows_out, rows_out is not None, out)

    # --------------------------------------------------------------------------------------------- contract
    def values(self, model: pin.Model, data: pin.Data, copy: bool = True) -> FloatArray:
        """``C_i`` per repulsor, (dim,), in [0, 1] (``copy=False``: the task's own array, read-only use, valid until
        the next evaluation)."""
        C = self._evaluate(model, data).C
        return C.copy() if copy else C

    def distances(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``||x - p_i||`` per repulsor, (dim,) [m]."""
        return self._evaluate(model, data).distances.copy()

    def active(self, model: pin.Model, data: pin.Data) -> npt.NDArray[np.bool_]:
        """True for the repulsors whose influence radius ``a_i`` contains the protected point, (dim,)."""
        return self._evaluate(model, data).distances < self._a

    def error(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``0 - C_i``, (dim,)."""
        return -self._evaluate(model, data).C

    def jacobian(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``grad C_i^T (J_x - J_p,i)``, (dim, nv)."""
        return self._evaluate(model, data).J.copy()

    def velocity(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``C_dot_i``, (dim,) [1/s]. Needs the acceleration-level update."""
        return self._evaluate_velocity(model, data).velocity.copy()

    def drift(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``J_dot_i v``, (dim,) [1/s^2]. Needs the acceleration-level update."""
        return self._evaluate_velocity(model, data).drift.copy()
