"""The rows of several frame tasks (:class:`~wbcbench.tasks.FrameTask`), contacts
(:class:`~wbcbench.tasks.Contact6D`) and CoM tasks (:class:`~wbcbench.tasks.CoMTask`) of a stack in one compiled
call.

A frame task's rows cost three pinocchio queries from Python per tick (``updateFramePlacement``,
``getFrameJacobian``, ``getFrameClassicalAcceleration``), a ``log3`` and a few numpy temporaries: 5-8 us a task,
six tasks in the teleoperation set (three on the head frame). Here one kernel computes, for every frame task of
the stack, the selected rows of the same quantities from what :func:`~wbcbench.tasks.update_kinematics` already
filled (pinocchio's joint Jacobians in WORLD ``data.J`` and their time variation ``data.dJ``, read in place) and
the frames' placements (forward kinematics of `ForwardKinematics`, compiled):

* placement ``(R, p)`` of the frame; error ``[p_ref - p; log3(R_ref R^T)]``;
* Jacobian (LOCAL_WORLD_ALIGNED): the WORLD columns of the joints supporting the frame, the linear part moved
  from the world origin to the frame, ``J_lin + J_ang x p``; the other columns zero;
* drift (classical acceleration at zero joint acceleration): with the spatial velocity ``(v_o, w) = J v`` and
  acceleration ``(a_o, w_dot) = dJ v`` at the world origin, ``p_ddot = a_o + w_dot x p + w x (v_o + w x p)``;
* a contact's rows are in its LOCAL frame: the Jacobian above rotated by ``R^T``, the error
  ``log6(M^-1 M_ref)`` (``w = log3(R^T R_ref)``, linear part ``V(w)^-1 R^T (p_ref - p)``; a contact with the
  split error ``[R^T (p_ref - p); w]``) and the drift the
  spatial acceleration ``R^T [a_o + w_dot x p; w_dot]`` (pinocchio's ``getFrameAcceleration``, LOCAL), or for a
  contact with the classical drift the classical acceleration above in the frame's axes, ``R^T [p_ddot; w_dot]``;
* each CoM task's rows from the centroidal map: ``Ag[:3] / m``, ``p_ref - com``, ``dAg[:3] v / m``.

The same quantities as pinocchio's to rounding (the tests compare them on random states), not the same bits: a
stack uses this path only when asked (``TaskStack(..., compiled_frames=True)``), so that the controllers whose
logs are compared bit for bit with earlier versions keep pinocchio's.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.jit import c_view, njit
from wbcbench.tasks.com_task import CoMTask
from wbcbench.tasks.exceptions import ReferenceNotSetError
from wbcbench.tasks.frame_task import FrameTask
from wbcbench.tasks.placements import ForwardKinematics, _forward

__all__ = ["FrameBatch", "classical_acceleration", "log3", "point_motion", "support_product"]

FloatArray = npt.NDArray[np.float64]


class FrameBatch:
    """The frame tasks, contacts and CoM tasks ``tasks`` of a stack, whose selected rows start at ``starts`` in the
    stack's buffers.

    `supported` is False when the model has a joint the compiled forward kinematics does not know (or there is no
    frame task or contact); the stack then keeps the tasks' own hooks.
    """

    def __init__(self, model: pin.Model, tasks, starts) -> None:
        self.fk = ForwardKinematics(model)
        pairs = list(zip(tasks, starts, strict=True))
        framed = [(t, start) for t, start in pairs if not isinstance(t, CoMTask)]
        self._com = [(t, start) for t, start in pairs if isinstance(t, CoMTask)]
        self.tasks = tuple(t for t, _ in framed)  # the frame tasks and contacts (the CoM tasks are `_com`)
        self.supported = self.fk.supported and len(framed) > 0
        if not self.supported:
            return
        nv = model.nv
        k = len(framed)
        parents, self._Rf, self._tf = self.fk.frame_arrays([t.frame_id for t in self.tasks])
        self._local = np.array([not isinstance(t, FrameTask) for t in self.tasks], dtype=np.bool_)
        self._classical = np.array([getattr(t, "drift_convention", "spatial") == "classical" for t in self.tasks],
                                   dtype=np.bool_)
        self._split = np.array([getattr(t, "error_convention", "log6") == "split" for t in self.tasks], dtype=np.bool_)
        # the CoM tasks' rows (e.g. com_xy and com_z, each with its own reference): one row per selected axis
        self._com_rows = np.array([start + r for t, start in self._com for r in range(len(t.rows))], dtype=np.intp)
        self._com_axes = np.array([a for t, _ in self._com for a in t.rows], dtype=np.intp)
        self._com_slices = []
        first = 0
        for t, _ in self._com:
            self._com_slices.append((t, slice(first, first + len(t.rows)), t.rows.astype(np.intp)))
            first += len(t.rows)
        masses = {float(t._inv_mass) for t, _ in self._com}
        if len(masses) > 1:
            raise ValueError("FrameBatch: CoM tasks of different models")
        self._com_inv_mass = masses.pop() if masses else 0.0
        self._com_ref = np.zeros(len(self._com_rows))  # per row, the reference of its task's axis
        self._com_seen: list = [None] * len(self._com)
        self._parents = parents
        support = np.zeros((k, nv), dtype=np.bool_)
        for i, j in enumerate(parents):
            for s in model.supports[int(j)]:
                if s > 0:
                    iv = model.joints[s].idx_v
                    support[i, iv:iv + model.joints[s].nv] = True
        self._support = support
        axes, owner, rows = [], [], []
        for i, (task, start) in enumerate(framed):
            for r, axis in enumerate(task.rows):
                axes.append(axis)
                owner.append(i)
                rows.append(start + r)
        self._axes = np.array(axes, dtype=np.intp)
        self._owner = np.array(owner, dtype=np.intp)
        self._rows = np.array(rows, dtype=np.intp)
        self._p_ref = np.zeros((k, 3))
        self._R_ref = np.zeros((k, 3, 3))
        self._seen: list = [None] * k
        self._R = np.zeros((k, 3, 3))
        self._t = np.zeros((k, 3))
        # the forward kinematics of the joints that carry the frames only (`ForwardKinematics.pruned`: the same
        # kernel and numbers, on TALOS' feet and base 14 joints of 34), the frames' parent joints numbered among them
        sub = self.fk.pruned(self._parents)
        kinds, jparents, idx_q, R0, t0 = sub._kinds, sub._parents, sub._idx_q, sub._R0, sub._t0
        self._parents = np.array([sub._index[int(j)] for j in self._parents], dtype=np.intp)
        n = len(kinds)
        # the kernel's own arrays (constants, references, work) in three buffers by type, these attributes views of
        # them: a compiled call types and unboxes each array argument (~40 ns each), and 36 arguments cost more
        # than a third of the call
        header = np.array([n, k, len(self._rows), len(self._com_rows), nv], dtype=np.intp)
        self._ints, (self._kinds, self._jparents, self._idx_q, self._parents, self._axes, self._owner, self._rows,
                     self._com_axes, self._com_rows) = _pack(
            [header, kinds, jparents, idx_q, self._parents, self._axes, self._owner, self._rows, self._com_axes,
             self._com_rows], np.intp, skip=1)
        self._floats, (self._R0, self._t0, self._Rj, self._tj, self._Rf, self._tf, self._R, self._t, self._p_ref,
                       self._R_ref, self._com_ref) = _pack(
            [R0, t0, np.zeros((n, 3, 3)), np.zeros((n, 3)), self._Rf, self._tf, self._R, self._t, self._p_ref,
             self._R_ref, self._com_ref], np.float64)
        self._flags, (self._support, self._local, self._classical, self._split) = _pack(
            [self._support, self._local, self._classical, self._split], np.bool_)
        self._args: tuple | None = None
        self._args_key: tuple = (None,) * 4

    def fill(self, model: pin.Model, data: pin.Data, A: FloatArray, e: FloatArray, drift: FloatArray | None) -> None:
        """Write the tasks' Jacobian rows into ``A``, error rows into ``e`` and, unless None, drift rows into
        ``drift`` (the stack's buffers), for the state of the last kinematics update."""
        seen, local = self._seen, self._local
        for i, task in enumerate(self.tasks):
            ref = task._R_ref
            if ref is not seen[i]:  # set_reference stores new arrays (contacts and frame tasks alike)
                if ref is None or task._p_ref is None:
                    what = "contact" if local[i] else "task"
                    raise ReferenceNotSetError(f"{task.owner}: call set_reference before evaluating the {what}")
                self._R_ref[i] = ref
                self._p_ref[i] = task._p_ref
                seen[i] = ref
        shared = _EMPTY
        if self._com:
            # the usual case, every CoM task with the same reference (`CoMTask.share_reference`): the kernel reads
            # it as it is; else each task's selected axes are copied when replaced
            first = self._com_slices[0][0]._p_ref
            for task, _, _ in self._com_slices:
                if task._p_ref is not first:
                    first = None
                    break
            if first is not None:
                shared = first
            else:
                com_ref, com_seen = self._com_ref, self._com_seen
                for i, (task, rows, axes) in enumerate(self._com_slices):
                    p_ref = task._p_ref
                    if p_ref is not com_seen[i]:  # set_reference stores a new array
                        if p_ref is None:
                            raise ReferenceNotSetError(f"{task.owner}: call set_reference before evaluating the task")
                        com_ref[rows] = p_ref[axes]
                        com_seen[i] = p_ref
        args, key = self._args, self._args_key
        if args is None or key[0] is not data or key[1] is not A or key[2] is not e or key[3] is not drift:
            args = self._args = self._arguments(data, A, e, drift)
            self._args_key = (data, A, e, drift)
        _frame_rows_packed(*args, shared)

    def _arguments(self, data: pin.Data, A: FloatArray, e: FloatArray, drift: FloatArray | None) -> tuple:
        """The kernel's arguments for these buffers: views of pinocchio's (fixed-size, filled in place by every
        kinematics update and ``data.q_in = q``), the stack's and our own three buffers, made once and reused."""
        with_drift = drift is not None
        if self._com:
            Ag, dAg, com = data.Ag, data.dAg, data.com[0]
        else:
            Ag = dAg = _EMPTY2
            com = _EMPTY
        return (data.q_in, self._ints, self._floats, self._flags, data.J, data.dJ if with_drift else data.J,
                data.v_in if with_drift else _EMPTY, A, e, drift if with_drift else _EMPTY, with_drift, Ag, dAg, com,
                self._com_inv_mass)


def _pack(arrays: list, dtype, skip: int = 0) -> tuple:
    """One flat buffer of ``dtype`` holding ``arrays`` one after the other (C order), and views of it shaped as
    the arrays (but the first ``skip`` ones)."""
    flat = [np.ascontiguousarray(a, dtype=dtype).ravel() for a in arrays]
    buf = np.concatenate(flat) if flat else np.zeros(0, dtype=dtype)
    views, start = [], 0
    for a, f in zip(arrays, flat):
        views.append(buf[start:start + f.size].reshape(np.shape(a)))
        start += f.size
    return buf, tuple(views[skip:])


_EMPTY = np.zeros(0)
_EMPTY2 = np.zeros((0, 0))


@njit
def log3(R, out):
    """The rotation vector of the rotation matrix ``R`` (3, 3) into ``out`` (3,) (pinocchio's ``log3``: angle in
    [0, pi])."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    c = 0.5 * (tr - 1.0)
    if c > 1.0:
        c = 1.0
    elif c < -1.0:
        c = -1.0
    vx = R[2, 1] - R[1, 2]
    vy = R[0, 2] - R[2, 0]
    vz = R[1, 0] - R[0, 1]
    # the angle from its sine (half the antisymmetric part's norm) and cosine: accurate at 0 and at pi, where acos
    # alone loses half the digits
    theta = math.atan2(0.5 * math.sqrt(vx * vx + vy * vy + vz * vz), c)
    if theta < 1e-4:  # theta / (2 sin theta) = 1/2 + theta^2 / 12 + O(theta^4)
        f = 0.5 + theta * theta / 12.0
        out[0], out[1], out[2] = f * vx, f * vy, f * vz
    elif theta < math.pi - 1e-3:
        f = theta / (2.0 * math.sin(theta))
        out[0], out[1], out[2] = f * vx, f * vy, f * vz
    else:
        # near pi the antisymmetric part vanishes: the axis from the symmetric part, R + R^T = 2 c I + 2 (1 - c) a a^T,
        # its sign from the antisymmetric part (2 sin(theta) a)
        d = 1.0 - c
        i = 0
        if R[1, 1] > R[i, i]:
            i = 1
        if R[2, 2] > R[i, i]:
            i = 2
        ai = math.sqrt(max((R[i, i] - c) / d, 0.0))
        a = np.empty(3)
        for j in range(3):
            a[j] = ai if j == i else (R[i, j] + R[j, i]) / (2.0 * d * ai)
        if a[0] * vx + a[1] * vy + a[2] * vz < 0.0:
            for j in range(3):
                a[j] = -a[j]
        for j in range(3):
            out[j] = theta * a[j]


@njit
def support_product(M, v, support):
    """``M[:, support] @ v[support]`` (6,) of a (6, nv) matrix, e.g. pinocchio's WORLD Jacobians ``data.J`` on the
    columns of the joints supporting a body: its spatial velocity at the world origin ``(v_o, w)``."""
    out = np.zeros(6)
    for c in range(M.shape[1]):
        if support[c]:
            vc = v[c]
            for a in range(6):
                out[a] += M[a, c] * vc
    return out


@njit
def point_motion(JW, dJ, v, support, p):
    """Of the point ``p`` (3,) of the body whose joints' columns are ``support``, at zero joint acceleration
    (pinocchio's WORLD Jacobians ``JW`` and their time variation ``dJ``, world axes): its velocity
    ``v_o + w x p``, the angular velocity ``w``, the spatial acceleration's linear part ``a_o + w_dot x p`` and the
    angular acceleration ``w_dot``, from ``(v_o, w) = J v`` and ``(a_o, w_dot) = dJ v`` at the world origin."""
    vo = support_product(JW, v, support)
    ao = support_product(dJ, v, support)
    px, py, pz = p[0], p[1], p[2]
    wx, wy, wz = vo[3], vo[4], vo[5]
    dx, dy, dz = ao[3], ao[4], ao[5]
    pd = np.empty(3)
    pd[0] = vo[0] + wy * pz - wz * py
    pd[1] = vo[1] + wz * px - wx * pz
    pd[2] = vo[2] + wx * py - wy * px
    a = np.empty(3)
    a[0] = ao[0] + dy * pz - dz * py
    a[1] = ao[1] + dz * px - dx * pz
    a[2] = ao[2] + dx * py - dy * px
    return pd, vo[3:], a, ao[3:]


@njit
def classical_acceleration(JW, dJ, v, support, p, out):
    """The classical acceleration at zero joint acceleration ``[p_ddot; w_dot]`` (6,, world axes) of the point
    ``p`` (3,) of that body into ``out``: ``p_ddot = a_o + w_dot x p + w x (v_o + w x p)`` (`point_motion`;
    pinocchio's ``getFrameClassicalAcceleration``, LOCAL_WORLD_ALIGNED)."""
    pd, w, a, wd = point_motion(JW, dJ, v, support, p)
    out[0] = a[0] + w[1] * pd[2] - w[2] * pd[1]
    out[1] = a[1] + w[2] * pd[0] - w[0] * pd[2]
    out[2] = a[2] + w[0] * pd[1] - w[1] * pd[0]
    out[3], out[4], out[5] = wd[0], wd[1], wd[2]


@njit(inline=True)
def _placements_at(buf, o, m):
    """Inside a kernel: ``m`` placements stored from ``buf[o]`` on (rotations (m, 3, 3), then translations (m, 3)),
    as views, and the offset after them."""
    return c_view(buf[o:o + 9 * m], (m, 3, 3)), c_view(buf[o + 9 * m:o + 12 * m], (m, 3)), o + 12 * m


@njit
def _frame_rows_packed(q, ints, floats, flags, J, dJ, v, A, e, drift, with_drift, Ag, dAg, com, inv_mass, com_shared):
    """`_frame_rows` with the batch's own arrays taken from its three buffers (`_pack`'s layout: ``ints`` = [joints
    kept, k, rows, CoM rows, nv], then the arrays, viewed by `jit.c_view`); ``com_shared`` (3,) the reference of
    every CoM task, or empty (then each row's from the buffer)."""
    n, k, n_rows, n_com, nv = ints[0], ints[1], ints[2], ints[3], ints[4]
    o = 5
    kinds = ints[o:o + n]
    jparents = ints[o + n:o + 2 * n]
    idx_q = ints[o + 2 * n:o + 3 * n]
    o += 3 * n
    parents = ints[o:o + k]
    o += k
    axes = ints[o:o + n_rows]
    owner = ints[o + n_rows:o + 2 * n_rows]
    rows = ints[o + 2 * n_rows:o + 3 * n_rows]
    o += 3 * n_rows
    com_axes = ints[o:o + n_com]
    com_rows = ints[o + n_com:o + 2 * n_com]
    R0, t0, f = _placements_at(floats, 0, n)
    Rj, tj, f = _placements_at(floats, f, n)
    Rf, tf, f = _placements_at(floats, f, k)
    R, t, f = _placements_at(floats, f, k)
    p_ref = c_view(floats[f:f + 3 * k], (k, 3))
    f += 3 * k
    R_ref = c_view(floats[f:f + 9 * k], (k, 3, 3))
    f += 9 * k
    com_ref = floats[f:f + n_com]
    support = c_view(flags[0:k * nv], (k, nv))
    local = flags[k * nv:k * nv + k]
    classical = flags[k * nv + k:k * nv + 2 * k]
    split = flags[k * nv + 2 * k:k * nv + 3 * k]
    _frame_rows(q, kinds, jparents, idx_q, R0, t0, Rj, tj, parents, Rf, tf, R, t, J, dJ, v, support, local,
                classical, split, p_ref, R_ref, axes, owner, rows, A, e, drift, with_drift, Ag, dAg, com, com_ref,
                com_axes, com_rows, inv_mass, com_shared)


@njit
def _frame_rows(q, kinds, jparents, idx_q, R0, t0, Rj, tj, parents, Rf, tf, R, t, J, dJ, v, support, local,
                classical, split, p_ref,
                R_ref, axes, owner, rows, A, e, drift, with_drift, Ag, dAg, com, com_ref, com_axes, com_rows, inv_mass,
                com_shared):
    # the CoM tasks' rows: Ag[:3] / m, p_ref - com, dAg[:3] v / m (p_ref: com_shared, else com_ref per row)
    shared = com_shared.shape[0] == 3
    for r in range(com_rows.shape[0]):
        ax, row = com_axes[r], com_rows[r]
        e[row] = (com_shared[ax] if shared else com_ref[r]) - com[ax]
        s = 0.0
        for c in range(Ag.shape[1]):
            A[row, c] = Ag[ax, c] * inv_mass
            if with_drift:
                s += dAg[ax, c] * v[c]
        if with_drift:
            drift[row] = s * inv_mass
    _forward(q, kinds, jparents, idx_q, R0, t0, Rj, tj)
    k = parents.shape[0]
    nv = J.shape[1]
    err = np.empty((k, 6))
    acc = np.empty((k, 6))
    M = np.empty((3, 3))
    w = np.empty(3)
    d = np.empty(3)
    ca = np.empty(6)
    for i in range(k):
        jp = parents[i]
        for a in range(3):
            for b in range(3):
                R[i, a, b] = Rj[jp, a, 0] * Rf[i, 0, b] + Rj[jp, a, 1] * Rf[i, 1, b] + Rj[jp, a, 2] * Rf[i, 2, b]
            t[i, a] = Rj[jp, a, 0] * tf[i, 0] + Rj[jp, a, 1] * tf[i, 1] + Rj[jp, a, 2] * tf[i, 2] + tj[jp, a]
        if local[i]:  # log6(M^-1 M_ref): w = log3(R^T R_ref), v = V(w)^-1 R^T (p_ref - p)
            for a in range(3):
                d[a] = 0.0
                for b in range(3):
                    M[a, b] = R[i, 0, a] * R_ref[i, 0, b] + R[i, 1, a] * R_ref[i, 1, b] + R[i, 2, a] * R_ref[i, 2, b]
                    d[a] += R[i, b, a] * (p_ref[i, b] - t[i, b])
            log3(M, w)
            if split[i]:  # [R^T (p_ref - p); log3(R^T R_ref)]
                err[i, 0], err[i, 1], err[i, 2] = d[0], d[1], d[2]
            else:
                th2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
                if th2 < 1e-8:  # (1 - th sin(th) / (2 (1 - cos(th)))) / th^2 = 1/12 + th^2 / 720 + O(th^4)
                    c = 1.0 / 12.0 + th2 / 720.0
                else:
                    th = math.sqrt(th2)
                    c = (1.0 - th * math.sin(th) / (2.0 * (1.0 - math.cos(th)))) / th2
                # V^-1 d = d - 1/2 w x d + c w x (w x d)
                wd0, wd1, wd2 = w[1] * d[2] - w[2] * d[1], w[2] * d[0] - w[0] * d[2], w[0] * d[1] - w[1] * d[0]
                err[i, 0] = d[0] - 0.5 * wd0 + c * (w[1] * wd2 - w[2] * wd1)
                err[i, 1] = d[1] - 0.5 * wd1 + c * (w[2] * wd0 - w[0] * wd2)
                err[i, 2] = d[2] - 0.5 * wd2 + c * (w[0] * wd1 - w[1] * wd0)
        else:
            for a in range(3):
                err[i, a] = p_ref[i, a] - t[i, a]
                for b in range(3):  # R_ref R^T
                    M[a, b] = R_ref[i, a, 0] * R[i, b, 0] + R_ref[i, a, 1] * R[i, b, 1] + R_ref[i, a, 2] * R[i, b, 2]
            log3(M, w)
        err[i, 3], err[i, 4], err[i, 5] = w[0], w[1], w[2]
        if with_drift:
            if local[i] and classical[i]:  # classical acceleration, in the frame's axes
                classical_acceleration(J, dJ, v, support[i], t[i], ca)
                for a in range(3):
                    acc[i, a] = R[i, 0, a] * ca[0] + R[i, 1, a] * ca[1] + R[i, 2, a] * ca[2]
                    acc[i, 3 + a] = R[i, 0, a] * ca[3] + R[i, 1, a] * ca[4] + R[i, 2, a] * ca[5]
            elif local[i]:  # spatial acceleration at the frame origin, in the frame's axes
                _, _, sa, wd = point_motion(J, dJ, v, support[i], t[i])
                for a in range(3):
                    acc[i, a] = R[i, 0, a] * sa[0] + R[i, 1, a] * sa[1] + R[i, 2, a] * sa[2]
                    acc[i, 3 + a] = R[i, 0, a] * wd[0] + R[i, 1, a] * wd[1] + R[i, 2, a] * wd[2]
            else:
                classical_acceleration(J, dJ, v, support[i], t[i], acc[i])
    col = np.empty(6)
    for r in range(rows.shape[0]):
        i = owner[r]
        ax = axes[r]
        row = rows[r]
        e[row] = err[i, ax]
        if with_drift:
            drift[row] = acc[i, ax]
        px, py, pz = t[i, 0], t[i, 1], t[i, 2]
        for c in range(nv):
            if not support[i, c]:
                A[row, c] = 0.0
                continue
            # the column in LOCAL_WORLD_ALIGNED: J_lin + J_ang x p, J_ang
            col[0] = J[0, c] + J[4, c] * pz - J[5, c] * py
            col[1] = J[1, c] + J[5, c] * px - J[3, c] * pz
            col[2] = J[2, c] + J[3, c] * py - J[4, c] * px
            col[3], col[4], col[5] = J[3, c], J[4, c], J[5, c]
            if local[i]:  # rotated into the frame's axes
                b = 0 if ax < 3 else 3
                a = ax - b
                A[row, c] = R[i, 0, a] * col[b] + R[i, 1, a] * col[b + 1] + R[i, 2, a] * col[b + 2]
            else:
                A[row, c] = col[ax]
