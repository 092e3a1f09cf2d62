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

from wbcbench.jit import njit

__all__ = ["ForwardKinematics"]

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
        return (np.array([m.frames[i].parentJoint for i in ids], dtype=np.intp),
                np.array([m.frames[i].placement.rotation for i in ids]),
                np.array([m.frames[i].placement.translation for i in ids]))

    def frames(self, q: FloatArray, arrays: tuple, R_out: FloatArray, t_out: FloatArray) -> None:
        """Placements of the frames of ``arrays`` (`frame_arrays`) for ``q`` into ``R_out`` (k, 3, 3), ``t_out``
        (k, 3), world."""
        _forward(q, self._kinds, self._parents, self._idx_q, self._R0, self._t0, self.R, self.t)
        _frames(self.R, self.t, *arrays, R_out, t_out)


@njit
def _forward(q, kinds, parents, idx_q, R0, t0, R, t):
    """``oMi[j] = oMi[parent] * jointPlacement[j] * M_j(q)`` for every joint in order (parents first)."""
    Rj = np.empty((3, 3))
    Rl = np.empty((3, 3))
    tl = np.empty(3)
    for a in range(3):
        for b in range(3):
            R[0, a, b] = 1.0 if a == b else 0.0
        t[0, a] = 0.0
    for j in range(1, kinds.shape[0]):
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
