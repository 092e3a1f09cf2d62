"""The placements of a model's joints and frames for a configuration (pinocchio's ``forwardKinematics`` then
``data.oMi`` / ``updateFramePlacement``) as one compiled call (see :mod:`wbcbench.jit`).

Reading ``data.oMi[j]`` from Python costs about 2 us per joint (an SE3 copy and two numpy conversions): the
self-collision tasks need a dozen joints per tick and the teleoperation stabilizer four frames on its own model.
Here the same products ``oMi = oMi[parent] * jointPlacement * M_joint(q)`` run in one kernel over arrays read
from the model once. Models of free-flyer and axis-aligned revolute joints (TALOS, G1) are supported;
`ForwardKinematics.supported` is False for any other joint type and callers then use pinocchio. The tests
check the placements against pinocchio's.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.jit import c_view, njit

__all__ = ["CenterOfMass", "ForwardKinematics", "forward_gather", "frame_placements", "joint_placements",
           "joint_placements_range", "subtree_sums"]

FloatArray = npt.NDArray[np.float64]

#: joint kinds of the kernel: the universe (index 0), the free flyer (q: x y z, quaternion x y z w), revolute
#: about the joint frame's x, y or z axis
_KINDS = {"JointModelFreeFlyer": 1, "JointModelRX": 2, "JointModelRY": 3, "JointModelRZ": 4}


class ForwardKinematics:
    """The joint placements ``oMi`` (rotations (njoints, 3, 3), translations (njoints, 3), world) and frame
    placements of ``model`` for a configuration, compiled.

    Args:
        model: the pinocchio model (its joint placements, parents and frames are copied: build again after
            changing the model).
    """

    def __init__(self, model: pin.Model):
        n = model.njoints
        kinds = np.zeros(n, dtype=np.intp)
        supported = True
        for j in range(1, n):
            kind = _KINDS.get(model.joints[j].shortname())
            if kind is None:
                supported = False
                break
            kinds[j] = kind
        self.supported = supported
        self.model = model
        self._kinds = kinds
        self._parents = np.array(model.parents, dtype=np.intp)
        self._idx_q = np.array([model.joints[j].idx_q if j > 0 else 0 for j in range(n)], dtype=np.intp)
        self._R0 = np.array([model.jointPlacements[j].rotation for j in range(n)])
        self._t0 = np.array([model.jointPlacements[j].translation for j in range(n)])
        self.R = np.zeros((n, 3, 3))
        self.t = np.zeros((n, 3))
        self._index: dict | None = None  # a pruned object's joint numbers (`pruned`)

    def pruned(self, joints) -> "ForwardKinematics":
        """The forward kinematics of ``joints`` (the model's joint indices) and their ancestors only, parents
        first: the same kernel and the same numbers on those joints, for a caller that needs nothing else (a
        foot's placement costs its leg, not the whole robot). Its arrays number the kept joints 0 (the universe),
        1, ...; its `frame_arrays` give the frames' parent joints in that numbering (frames of kept joints only)."""
        keep = sorted({0} | {int(a) for j in joints for a in self.model.supports[int(j)]})
        index = {j: i for i, j in enumerate(keep)}
        sub = object.__new__(ForwardKinematics)
        sub.supported, sub.model, sub._index = self.supported, self.model, index
        sub._kinds, sub._idx_q = self._kinds[keep], self._idx_q[keep]
        sub._parents = np.array([index[int(self._parents[j])] for j in keep], dtype=np.intp)
        sub._R0, sub._t0 = self._R0[keep], self._t0[keep]
        sub.R, sub.t = np.zeros((len(keep), 3, 3)), np.zeros((len(keep), 3))
        return sub

    def joints(self, q: FloatArray, joints=None, R_out: FloatArray | None = None,
               t_out: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
        """``oMi`` for ``q`` (nq,): of every joint, rotations (njoints, 3, 3) and translations (njoints, 3) in the
        object's own buffers (overwritten by the next call); or of the joints ``joints`` (k,) (an index array)
        into ``R_out`` (k, 3, 3), ``t_out`` (k, 3)."""
        if joints is None:
            _forward(q, self._kinds, self._parents, self._idx_q, self._R0, self._t0, self.R, self.t)
            return self.R, self.t
        _forward_gather(q, self._kinds, self._parents, self._idx_q, self._R0, self._t0, self.R, self.t, joints, R_out,
                        t_out)
        return R_out, t_out

    def frame_arrays(self, frame_ids) -> tuple:
        """The constant inputs of `frames` for the frames ``frame_ids``: their parent joints and placements in
        them."""
        m = self.model
        ids = [int(i) for i in frame_ids]
        index = self._index
        return (np.array([m.frames[i].parentJoint if index is None else index[m.frames[i].parentJoint]
                          for i in ids], dtype=np.intp),
                np.array([m.frames[i].placement.rotation for i in ids]),
                np.array([m.frames[i].placement.translation for i in ids]))

    def frames(self, q: FloatArray, arrays: tuple, R_out: FloatArray, t_out: FloatArray) -> None:
        """Placements of the frames of ``arrays`` (`frame_arrays`) for ``q`` into ``R_out`` (k, 3, 3), ``t_out``
        (k, 3), world."""
        _forward(q, self._kinds, self._parents, self._idx_q, self._R0, self._t0, self.R, self.t)
        _frames(self.R, self.t, *arrays, R_out, t_out)

    def frames_along(self, Q: FloatArray, arrays: tuple) -> tuple[FloatArray, FloatArray]:
        """`frames` for every row of ``Q`` (N, nq) (e.g. a run's logged configurations, quaternions normalised):
        rotations (N, k, 3, 3) and translations (N, k, 3), in one compiled call."""
        n, k = Q.shape[0], arrays[0].shape[0]
        R_out, t_out = np.empty((n, k, 3, 3)), np.empty((n, k, 3))
        _frames_along(np.ascontiguousarray(Q, dtype=float), self._kinds, self._parents, self._idx_q, self._R0,
                      self._t0, self.R, self.t, *arrays, R_out, t_out)
        return R_out, t_out


class CenterOfMass:
    """The centre of mass of ``model`` and its velocity for (q, v), compiled: pinocchio's
    ``centerOfMass(model, data, q, v)`` (``data.com[0]``, ``data.vcom[0]``) with the sums in another order (equal
    to rounding; the tests compare them). For free-flyer and axis-aligned revolute joints
    (`ForwardKinematics.supported`).

    The velocity is the Jacobian's sum over the joints: a revolute joint j turning at qdot_j about its world axis
    a_j moves its subtree's centre of mass at ``qdot_j a_j x (c_j - o_j)``, weighted by the subtree's mass; the
    free flyer moves everything as a rigid body (its velocity in its own frame, as pinocchio's)."""

    def __init__(self, model: pin.Model):
        self.fk = ForwardKinematics(model)
        self.supported = self.fk.supported
        n = model.njoints
        self._idx_v = np.array([model.joints[j].idx_v if j > 0 else 0 for j in range(n)], dtype=np.intp)
        self._mass = np.array([model.inertias[j].mass for j in range(n)])
        self._lever = np.array([model.inertias[j].lever for j in range(n)])
        self._msub = np.zeros(n)
        self._csub = np.zeros((n, 3))

    def write(self, x: FloatArray, iq: int, iv: int, out: int) -> None:
        """Read q at ``x[iq:iq+nq]`` and v at ``x[iv:iv+nv]``; write the CoM [m] and its velocity [m/s], world, at
        ``x[out:out+6]`` (e.g. one log row holding all three)."""
        fk = self.fk
        _center_of_mass(x, iq, iv, out, fk._kinds, fk._parents, fk._idx_q, self._idx_v, fk._R0, fk._t0, self._mass,
                        self._lever, fk.R, fk.t, self._msub, self._csub)

    def write_rows(self, rows: FloatArray, iq: int, iv: int, out: int) -> None:
        """`write` for each row of ``rows`` (n, columns) in one call (without the GIL: e.g. a log block in a
        writer thread). Not to be called from two threads at once (the object's work arrays)."""
        fk = self.fk
        _center_of_mass_rows(rows, iq, iv, out, fk._kinds, fk._parents, fk._idx_q, self._idx_v, fk._R0, fk._t0,
                             self._mass, self._lever, fk.R, fk.t, self._msub, self._csub)


@njit
def _center_of_mass(x, iq, iv, out, kinds, parents, idx_q, idx_v, R0, t0, mass, lever, R, t, msub, csub):
    """`CenterOfMass.write`: placements, each body's mass-weighted centre, the subtrees' sums (children after
    their parents in pinocchio's order), then the CoM and its velocity."""
    n = kinds.shape[0]
    _forward(x[iq:], kinds, parents, idx_q, R0, t0, R, t)
    _subtree_sums(R, t, parents, mass, lever, msub, csub)
    total = msub[0]
    vx = vy = vz = 0.0
    for j in range(1, n):
        # the subtree's first moment about the joint's origin: sum of m_i (c_i - o_j)
        rx = csub[j, 0] - msub[j] * t[j, 0]
        ry = csub[j, 1] - msub[j] * t[j, 1]
        rz = csub[j, 2] - msub[j] * t[j, 2]
        k = kinds[j]
        i = iv + idx_v[j]
        if k == 1:  # linear then angular velocity, in the joint's frame
            lx, ly, lz = x[i], x[i + 1], x[i + 2]
            wx_, wy_, wz_ = x[i + 3], x[i + 4], x[i + 5]
            ax = R[j, 0, 0] * wx_ + R[j, 0, 1] * wy_ + R[j, 0, 2] * wz_
            ay = R[j, 1, 0] * wx_ + R[j, 1, 1] * wy_ + R[j, 1, 2] * wz_
            az = R[j, 2, 0] * wx_ + R[j, 2, 1] * wy_ + R[j, 2, 2] * wz_
            m = msub[j]
            vx += m * (R[j, 0, 0] * lx + R[j, 0, 1] * ly + R[j, 0, 2] * lz)
            vy += m * (R[j, 1, 0] * lx + R[j, 1, 1] * ly + R[j, 1, 2] * lz)
            vz += m * (R[j, 2, 0] * lx + R[j, 2, 1] * ly + R[j, 2, 2] * lz)
        else:
            c = k - 2
            w = x[i]
            ax, ay, az = R[j, 0, c] * w, R[j, 1, c] * w, R[j, 2, c] * w
        vx += ay * rz - az * ry
        vy += az * rx - ax * rz
        vz += ax * ry - ay * rx
    for a in range(3):
        x[out + a] = csub[0, a] / total
    x[out + 3] = vx / total
    x[out + 4] = vy / total
    x[out + 5] = vz / total


@njit
def _subtree_sums(R, t, parents, mass, lever, msub, csub):
    """From the joint placements ``R``, ``t``: each subtree's mass ``msub`` and first moment ``csub`` (sum of m_i
    c_i, world), children after their parents in pinocchio's order; the CoM is ``csub[0] / msub[0]``."""
    n = parents.shape[0]
    for j in range(n):
        m = mass[j]
        msub[j] = m
        for a in range(3):
            csub[j, a] = m * (R[j, a, 0] * lever[j, 0] + R[j, a, 1] * lever[j, 1] + R[j, a, 2] * lever[j, 2]
                              + t[j, a])
    for j in range(n - 1, 0, -1):
        p = parents[j]
        msub[p] += msub[j]
        for a in range(3):
            csub[p, a] += csub[j, a]


@njit
def _center_of_mass_rows(rows, iq, iv, out, kinds, parents, idx_q, idx_v, R0, t0, mass, lever, R, t, msub, csub):
    """`_center_of_mass` on each row."""
    for r in range(rows.shape[0]):
        _center_of_mass(rows[r], iq, iv, out, kinds, parents, idx_q, idx_v, R0, t0, mass, lever, R, t, msub, csub)


@njit
def _forward(q, kinds, parents, idx_q, R0, t0, R, t):
    """``oMi[j] = oMi[parent] * jointPlacement[j] * M_j(q)`` for every joint in order (parents first)."""
    _forward_range(q, kinds, parents, idx_q, R0, t0, R, t, 0, kinds.shape[0], np.empty(21))


@njit
def _forward_range(q, kinds, parents, idx_q, R0, t0, R, t, lo, hi, work):
    """`_forward` for the joints ``lo`` to ``hi - 1`` only (0: from the universe), those before ``lo`` already
    placed in ``R``, ``t``: the joints a caller needs (a prefix of the order holds their ancestors) and later the
    rest, the same numbers as one pass. ``work`` (21,): scratch (a joint's motion and its placement in its
    parent)."""
    Rj = c_view(work[0:9], (3, 3))
    Rl = c_view(work[9:18], (3, 3))
    tl = work[18:21]
    if lo == 0:
        for a in range(3):
            for b in range(3):
                R[0, a, b] = 1.0 if a == b else 0.0
            t[0, a] = 0.0
        lo = 1
    for j in range(lo, hi):
        k = kinds[j]
        iq = idx_q[j]
        if k == 1:
            # Eigen's Quaternion::toRotationMatrix (x, y, z, w), as pinocchio's free flyer
            x, y, z, w = q[iq + 3], q[iq + 4], q[iq + 5], q[iq + 6]
            tx, ty, tz = 2.0 * x, 2.0 * y, 2.0 * z
            twx, twy, twz = tx * w, ty * w, tz * w
            txx, txy, txz = tx * x, ty * x, tz * x
            tyy, tyz, tzz = ty * y, tz * y, tz * z
            Rj[0, 0], Rj[0, 1], Rj[0, 2] = 1.0 - (tyy + tzz), txy - twz, txz + twy
            Rj[1, 0], Rj[1, 1], Rj[1, 2] = txy + twz, 1.0 - (txx + tzz), tyz - twx
            Rj[2, 0], Rj[2, 1], Rj[2, 2] = txz - twy, tyz + twx, 1.0 - (txx + tyy)
            tj0, tj1, tj2 = q[iq], q[iq + 1], q[iq + 2]
        else:
            c, s = np.cos(q[iq]), np.sin(q[iq])
            for a in range(3):
                for b in range(3):
                    Rj[a, b] = 0.0
            if k == 2:
                Rj[0, 0], Rj[1, 1], Rj[1, 2], Rj[2, 1], Rj[2, 2] = 1.0, c, -s, s, c
            elif k == 3:
                Rj[1, 1], Rj[0, 0], Rj[0, 2], Rj[2, 0], Rj[2, 2] = 1.0, c, s, -s, c
            else:
                Rj[2, 2], Rj[0, 0], Rj[0, 1], Rj[1, 0], Rj[1, 1] = 1.0, c, -s, s, c
            tj0 = tj1 = tj2 = 0.0
        # liMi = jointPlacement * M_j
        for a in range(3):
            for b in range(3):
                Rl[a, b] = R0[j, a, 0] * Rj[0, b] + R0[j, a, 1] * Rj[1, b] + R0[j, a, 2] * Rj[2, b]
            tl[a] = R0[j, a, 0] * tj0 + R0[j, a, 1] * tj1 + R0[j, a, 2] * tj2 + t0[j, a]
        # oMi = oMi[parent] * liMi
        p = parents[j]
        for a in range(3):
            for b in range(3):
                R[j, a, b] = R[p, a, 0] * Rl[0, b] + R[p, a, 1] * Rl[1, b] + R[p, a, 2] * Rl[2, b]
            t[j, a] = R[p, a, 0] * tl[0] + R[p, a, 1] * tl[1] + R[p, a, 2] * tl[2] + t[p, a]


@njit
def _frames(R, t, parent, Rf, tf, R_out, t_out):
    """``oMf = oMi[parent] * placement`` for each frame."""
    for i in range(parent.shape[0]):
        p = parent[i]
        for a in range(3):
            for b in range(3):
                R_out[i, a, b] = R[p, a, 0] * Rf[i, 0, b] + R[p, a, 1] * Rf[i, 1, b] + R[p, a, 2] * Rf[i, 2, b]
            t_out[i, a] = R[p, a, 0] * tf[i, 0] + R[p, a, 1] * tf[i, 1] + R[p, a, 2] * tf[i, 2] + t[p, a]


@njit
def _frames_along(Q, kinds, parents, idx_q, R0, t0, R, t, parent, Rf, tf, R_out, t_out):
    """`_forward` then `_frames` for each row of Q."""
    for r in range(Q.shape[0]):
        _forward(Q[r], kinds, parents, idx_q, R0, t0, R, t)
        _frames(R, t, parent, Rf, tf, R_out[r], t_out[r])


@njit
def _gather(R, t, joints, R_out, t_out):
    """``R_out[k], t_out[k] = R[joints[k]], t[joints[k]]``."""
    for k in range(joints.shape[0]):
        j = joints[k]
        for a in range(3):
            for b in range(3):
                R_out[k, a, b] = R[j, a, b]
            t_out[k, a] = t[j, a]


@njit
def _forward_gather(q, kinds, parents, idx_q, R0, t0, R, t, joints, R_out, t_out):
    """`_forward`, then `_gather` (one call)."""
    _forward(q, kinds, parents, idx_q, R0, t0, R, t)
    _gather(R, t, joints, R_out, t_out)


# The kernels other packages call from their own compiled kernels (estimation, stabilizers), under public names:
# the arrays they take are those of `ForwardKinematics` and `CenterOfMass`.
joint_placements = _forward
"""``joint_placements(q, kinds, parents, idx_q, R0, t0, R, t)``: every joint's placement into ``R``, ``t``."""
joint_placements_range = _forward_range
"""``joint_placements_range(q, kinds, parents, idx_q, R0, t0, R, t, lo, hi, work)``: the placements of the joints
``lo`` to ``hi - 1`` into ``R``, ``t``, those before ``lo`` already there (0: from the universe); ``work`` (21,)
scratch."""
frame_placements = _frames
"""``frame_placements(R, t, parent, Rf, tf, R_out, t_out)``: frames' placements from their joints'."""
subtree_sums = _subtree_sums
"""``subtree_sums(R, t, parents, mass, lever, msub, csub)``: each subtree's mass and first moment."""
forward_gather = _forward_gather
"""``forward_gather(q, kinds, parents, idx_q, R0, t0, R, t, joints, R_out, t_out)``: `joint_placements`, then
the placements of ``joints`` gathered into ``R_out``, ``t_out``."""
