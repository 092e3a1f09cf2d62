"""The joint placements of the last two configurations of a model, shared by its estimators' compiled kernels.

A position-controlled controller's tick asks for the placements of the same two configurations several times: the
base feedback (the soles of the integrated model and of the measured robot) and the balance estimator (the measured
robot's CoM and F/T sensors, the model's soles) each ran the forward kinematics of both. `memo_joint_placements`
keeps the last two configurations it was given (bit for bit) with their placements, so that each is computed once a
tick; the placements are the same numbers either way (the same kernel on the same input).

A caller asks for the joints it needs, a prefix of the joint order (parents come first: the prefix up to a frame's
joint holds its ancestors): the base feedback needs the soles of both configurations, the balance estimator the
whole measured robot (its CoM) and the model's soles. A slot keeps how many joints it has placed and places more
only when asked for them: the model's arms and head are never computed.

One memo per pinocchio model in a process (`placement_memo`), shared by every estimator built on it; not
thread-safe.
"""

from __future__ import annotations

import weakref

import numpy as np
import pinocchio as pin

from ..jit import c_view, njit
from ..tasks.placements import ForwardKinematics, joint_placements_range

__all__ = ["PlacementMemo", "joints_placing", "memo_arrays", "memo_joint_placements", "placement_memo"]


class PlacementMemo:
    """Two slots of (configuration, joint placements); `state`: the slot to overwrite next, then the number of joints
    each slot has placed (a prefix of the order); `work`: the forward kinematics' scratch; `args` are the arrays
    `memo_joint_placements` takes between the model's constants and ``upto``."""

    def __init__(self, fk: ForwardKinematics, nq: int):
        n = fk.R.shape[0]
        # the model's kinematic constants and the slots in two buffers (`ints`, `floats`: `memo_arrays` views them
        # inside a kernel), these attributes views of them: two arguments of a compiled call instead of nine
        self.ints = np.concatenate([np.array([n, nq], dtype=np.intp), fk._kinds, fk._parents, fk._idx_q,
                                    np.zeros(3, dtype=np.intp)])
        self.floats = np.concatenate([fk._R0.ravel(), fk._t0.ravel(), np.full(2 * nq, np.nan),  # NaN: no configuration
                                      np.zeros(2 * n * 9), np.zeros(2 * n * 3), np.zeros(21)])  # the kernel's scratch
        o = 12 * n
        self.q = self.floats[o:o + 2 * nq].reshape(2, nq)
        self.R = self.floats[o + 2 * nq:o + 2 * nq + 18 * n].reshape(2, n, 3, 3)
        self.t = self.floats[o + 2 * nq + 18 * n:o + 2 * nq + 24 * n].reshape(2, n, 3)
        self.work = self.floats[o + 2 * nq + 24 * n:]
        self.state = self.ints[2 + 3 * n:]
        self.args = (self.q, self.R, self.t, self.state, self.work)


_MEMOS: dict[tuple[int, bytes], PlacementMemo] = {}


def placement_memo(model: pin.Model, fk: ForwardKinematics) -> PlacementMemo:
    """The memo of `model` and its compiled forward kinematics `fk`, made at the first call (one per model and
    kinematic constants: a model changed between two `ForwardKinematics` gets another)."""
    key = (id(model), b"".join(a.tobytes() for a in (fk._kinds, fk._parents, fk._idx_q, fk._R0, fk._t0)))
    memo = _MEMOS.get(key)
    if memo is None:
        memo = _MEMOS[key] = PlacementMemo(fk, model.nq)
        weakref.finalize(model, _MEMOS.pop, key, None)
    return memo


@njit
def memo_joint_placements(q, kinds, parents, idx_q, R0, t0, memo_q, memo_R, memo_t, memo_state, memo_work, upto):
    """The slot (0 or 1) of ``memo_R``, ``memo_t`` holding the placements of the joints 0 to ``upto - 1`` of
    ``q``: a slot whose configuration is ``q`` bit for bit (the sign of zero included), its later joints placed if
    it had fewer (`placements.joint_placements_range`, with the scratch ``memo_work``), else the older slot,
    computed up to ``upto``."""
    n = q.shape[0]
    for slot in range(2):
        same = True
        for i in range(n):
            a, b = q[i], memo_q[slot, i]
            if not (a == b and np.signbit(a) == np.signbit(b)):
                same = False
                break
        if same:
            done = memo_state[1 + slot]
            if done < upto:
                joint_placements_range(q, kinds, parents, idx_q, R0, t0, memo_R[slot], memo_t[slot], done, upto,
                                       memo_work)
                memo_state[1 + slot] = upto
            return slot
    slot = memo_state[0]
    memo_state[0] = 1 - slot
    memo_q[slot, 0] = np.nan  # not valid while the placements are written
    joint_placements_range(q, kinds, parents, idx_q, R0, t0, memo_R[slot], memo_t[slot], 0, upto, memo_work)
    memo_state[1 + slot] = upto
    for i in range(n):
        memo_q[slot, i] = q[i]
    return slot


@njit(inline=True)
def joints_placing(frame_parents):
    """The prefix of the joint order that places the frames whose parent joints are ``frame_parents``: its length,
    the last of those joints + 1 (`memo_joint_placements`' ``upto``)."""
    upto = 1
    for p in frame_parents:
        upto = max(upto, p + 1)
    return upto


@njit(inline=True)
def memo_arrays(ints, floats):
    """Inside a kernel, the arrays of a `PlacementMemo` from its two buffers: ``(kinds, parents, idx_q, R0, t0,
    memo_q, memo_R, memo_t, memo_state, memo_work)``, the arguments `memo_joint_placements` takes between ``q`` and
    ``upto`` (views made by `c_view`, cheaper than numba's reshape)."""
    n, nq = ints[0], ints[1]
    kinds = ints[2:2 + n]
    parents = ints[2 + n:2 + 2 * n]
    idx_q = ints[2 + 2 * n:2 + 3 * n]
    memo_state = ints[2 + 3 * n:5 + 3 * n]
    R0 = c_view(floats[0:9 * n], (n, 3, 3))
    t0 = c_view(floats[9 * n:12 * n], (n, 3))
    o = 12 * n
    memo_q = c_view(floats[o:o + 2 * nq], (2, nq))
    memo_R = c_view(floats[o + 2 * nq:o + 2 * nq + 18 * n], (2, n, 3, 3))
    memo_t = c_view(floats[o + 2 * nq + 18 * n:o + 2 * nq + 24 * n], (2, n, 3))
    memo_work = floats[o + 2 * nq + 24 * n:o + 2 * nq + 24 * n + 21]
    return kinds, parents, idx_q, R0, t0, memo_q, memo_R, memo_t, memo_state, memo_work
