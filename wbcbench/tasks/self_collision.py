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
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.tasks import _validation as val
from wbcbench.tasks.exceptions import TaskConfigError
from wbcbench.tasks.task import Task

__all__ = ["RepulsionPoint", "SelfCollisionTask", "attractor"]

FloatArray = npt.NDArray[np.float64]

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def _skew(r: FloatArray) -> FloatArray:
    x, y, z = r
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a x b`` for (3,) vectors (np.cross costs ~20x more on one pair: it is called 50 times per tick)."""
    a0, a1, a2 = a
    b0, b1, b2 = b
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _skew_times(r: FloatArray, A: FloatArray) -> FloatArray:
    """``skew(r_i) @ A_i`` for the rows r_i of r (n, 3) and the matrices A_i of A (n, 3, nv): (n, 3, nv)."""
    out = np.empty(A.shape)
    x, y, z = r[:, 0, None], r[:, 1, None], r[:, 2, None]
    np.subtract(y * A[:, 2], z * A[:, 1], out=out[:, 0])
    np.subtract(z * A[:, 0], x * A[:, 2], out=out[:, 1])
    np.subtract(x * A[:, 1], y * A[:, 0], out=out[:, 2])
    return out


def _cross_rows(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a_i x b_i`` for the rows of a and b (n, 3)."""
    out = np.empty(b.shape)
    np.subtract(a[:, 1] * b[:, 2], a[:, 2] * b[:, 1], out=out[:, 0])
    np.subtract(a[:, 2] * b[:, 0], a[:, 0] * b[:, 2], out=out[:, 1])
    np.subtract(a[:, 0] * b[:, 1], a[:, 1] * b[:, 0], out=out[:, 2])
    return out


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


def _attractors(r: FloatArray, exponent: float, scales: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`attractor` for n vectors at once: ``r`` (n, 3), ``scales`` (n,) -> C (n,), grad (n, 3), H (n, 3, 3)."""
    p = float(exponent)
    d = np.sqrt(np.einsum("ni,ni->n", r, r))
    C = np.exp(-(d**p) / scales)
    k = p / scales
    with np.errstate(divide="ignore", invalid="ignore"):
        dp2 = np.where(d > 0.0, d ** (p - 2.0), 1.0 if p == 2.0 else 0.0)
        dp4 = np.where(d > 0.0, d ** (p - 4.0), 0.0) if p != 2.0 else np.zeros_like(d)
    g = (-k * dp2 * C)[:, None] * r
    coeff = k * k * dp2 * dp2 - (k * (p - 2.0) * dp4 if p != 2.0 else 0.0)
    H = C[:, None, None] * (coeff[:, None, None] * np.einsum("ni,nj->nij", r, r)
                            - (k * dp2)[:, None, None] * np.eye(3))
    return C, g, H


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
    key: tuple[int, bytes] | None = None
    vkey: bytes | None = None
    C: FloatArray = field(default_factory=lambda: np.zeros(0))
    grads: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    hessians: FloatArray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    J_rel: FloatArray = field(default_factory=lambda: np.zeros((0, 3, 0)))
    J: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    distances: FloatArray = field(default_factory=lambda: np.zeros(0))
    velocity: FloatArray = field(default_factory=lambda: np.zeros(0))
    drift: FloatArray = field(default_factory=lambda: np.zeros(0))


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
        kp: 1/s^2, scalar or one per repulsor (Table I: 500).
        kd: 1/s; default ``2 sqrt(kp)``.
        weight: QP weight (Table I: 700).
        mask: one entry per repulsor.
        name: task name, default ``"self_collision-<frame>"``.

    Raises:
        UnknownNameError: unknown frame (the message lists close names).
        TaskConfigError: no repulsor, negative radius, ``r_rep + r_frame = 0``, ``p < 2``, duplicate axis name,
            invalid gain, mask or weight.
    """

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
        weight: float = 1.0,
        mask: Sequence[bool | int] | None = None,
        name: str | None = None,
    ) -> None:
        task_name = f"self_collision-{frame}" if name is None else name
        owner = f"{type(self).__name__} {task_name!r}"
        self._frame_id = val.find_frame(model, frame, owner)
        self._frame = frame
        self._offset = val.frozen(val.as_vector(offset, 3, owner, "offset"))
        self._radius = val.as_scalar(radius, owner, "radius")
        self._exponent = val.as_scalar(exponent, owner, "exponent", minimum=2.0)
        self._normalized = bool(normalized)
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
        # the frames carrying repulsors (each evaluated once per tick) and, per repulsor, the index of its frame
        self._frames = tuple(dict.fromkeys(ids))
        self._frame_of = np.array([self._frames.index(fid) for fid in ids], dtype=np.intp)
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
    @staticmethod
    def _point(model: pin.Model, data: pin.Data, frame_id: int, offset: FloatArray) -> tuple[FloatArray, FloatArray]:
        """World position (3,) and world-axes linear Jacobian (3, nv) of ``offset`` in frame ``frame_id``."""
        M = pin.updateFramePlacement(model, data, frame_id)
        r = M.rotation @ offset
        J6 = pin.getFrameJacobian(model, data, frame_id, _LWA)
        J = J6[:3] - pin.skew(r) @ J6[3:]
        return M.translation + r, J

    @staticmethod
    def _point_drift(model: pin.Model, data: pin.Data, frame_id: int, offset: FloatArray) -> FloatArray:
        """Classical acceleration (3,) of the point at zero joint acceleration, world axes."""
        M = data.oMf[frame_id]
        r = M.rotation @ offset
        vel = pin.getFrameVelocity(model, data, frame_id, _LWA)
        acc = pin.getFrameClassicalAcceleration(model, data, frame_id, _LWA)
        w = vel.angular
        return acc.linear + _cross(acc.angular, r) + _cross(w, _cross(w, r))

    def _evaluate(self, model: pin.Model, data: pin.Data) -> _Cache:
        """Position-level quantities, cached per (data, q). Each frame carrying repulsors is evaluated once."""
        q = np.asarray(data.q_in)
        key = (id(data), q.tobytes())
        cache = self._cache
        if cache.key == key:
            return cache
        x, Jx = self._point(model, data, self._frame_id, self._offset)
        n = self.dim
        nf = len(self._frames)
        R = np.empty((nf, 3, 3))
        t = np.empty((nf, 3))
        J6 = np.empty((nf, 6, model.nv))
        for k, fid in enumerate(self._frames):  # pinocchio once per carrying frame
            M = pin.updateFramePlacement(model, data, fid)
            R[k], t[k] = M.rotation, M.translation
            J6[k] = pin.getFrameJacobian(model, data, fid, _LWA)
        f = self._frame_of
        R, J6 = R[f], J6[f]
        r = np.einsum("nij,nj->ni", R, self._rep_offsets)  # offsets in world axes, (n, 3)
        points = t[f] + r
        # J_x - J_p with J_p = J6[:3] - skew(r) J6[3:], every repulsor at once
        J_rel = Jx - J6[:, :3]
        J_rel += _skew_times(r, J6[:, 3:])
        rel = x - points
        C, grads, hessians = _attractors(rel, self._exponent, self._scales)
        distances = np.sqrt(np.einsum("ni,ni->n", rel, rel))
        self._cache = _Cache(
            key=key, C=C, grads=grads, hessians=hessians, J_rel=J_rel, distances=distances,
            J=np.einsum("nk,nkv->nv", grads, J_rel),
        )
        return self._cache

    def _evaluate_velocity(self, model: pin.Model, data: pin.Data) -> _Cache:
        cache = self._evaluate(model, data)
        v = np.asarray(data.v_in)
        vkey = v.tobytes()
        if cache.vkey == vkey:
            return cache
        r_dot = cache.J_rel @ v  # (n, 3)
        ax = self._point_drift(model, data, self._frame_id, self._offset)
        nf = len(self._frames)
        R = np.empty((nf, 3, 3))
        w = np.empty((nf, 3))
        a_lin = np.empty((nf, 3))
        a_ang = np.empty((nf, 3))
        for k, fid in enumerate(self._frames):
            vel = pin.getFrameVelocity(model, data, fid, _LWA)
            acc = pin.getFrameClassicalAcceleration(model, data, fid, _LWA)
            R[k], w[k], a_lin[k], a_ang[k] = data.oMf[fid].rotation, vel.angular, acc.linear, acc.angular
        f = self._frame_of
        w = w[f]
        r = np.einsum("nij,nj->ni", R[f], self._rep_offsets)
        a_rep = a_lin[f] + _cross_rows(a_ang[f], r) + _cross_rows(w, _cross_rows(w, r))
        drift = (np.einsum("ni,nij,nj->n", r_dot, cache.hessians, r_dot)
                 + np.einsum("ni,ni->n", cache.grads, ax - a_rep))
        cache.velocity = cache.J @ v
        cache.drift = drift
        cache.vkey = vkey
        return cache

    # --------------------------------------------------------------------------------------------- contract
    def values(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``C_i`` per repulsor, (dim,), in [0, 1]."""
        return self._evaluate(model, data).C.copy()

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
