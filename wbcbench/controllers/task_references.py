"""References -> task targets: the one path by which a tick's `References` reach a formulation's tasks, shared by
the inverse-dynamics and the kinematic formulations (a velocity-level task ignores the accelerations)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..jit import njit
from ..side import Side
from ..tasks import CoMTask, FrameTask, Task
from ..types import JointReference, PoseReference, References

__all__ = ["TaskReferences", "with_swing_pitch"]


def with_swing_pitch(feet: Mapping, pitch: Mapping, axes: Mapping | None = None) -> dict:
    """The swing feet's references with the plan's pitch offsets (`References.swing_pitch`) added: each foot's
    rotation turned about its own lateral (y) axis by delta, the angular velocity and acceleration (world axes)
    with delta's rate and acceleration about that axis (the axis turning with the planned rotation); positions and
    feet without an offset (or without a rotation) as they are (an offset of 4 values: the first 3; a toe-off's
    swing, whose planned positions already carry the turn about the toe). axes: per side, a world axis (3,) to turn
    about instead of the foot's own lateral one (the rate and acceleration about it as given)."""
    out = dict(feet)
    for side, d in pitch.items():
        foot = feet.get(side)
        if foot is None or foot.rotation is None:
            continue
        axis = axes.get(side) if axes else None
        R_new, v, a = np.empty((3, 3)), np.empty(6), np.empty(6)
        _pitched(foot.rotation, float(d[0]), float(d[1]), float(d[2]), _NO_AXIS if axis is None else
                 np.asarray(axis, dtype=float), np.asarray(foot.velocity, dtype=float),
                 np.asarray(foot.acceleration, dtype=float), R_new, v, a)
        out[side] = PoseReference.unchecked(np.asarray(foot.position, dtype=float), R_new, v, a)
    return out


_NO_AXIS = np.zeros(0)


@njit
def _pitched(R, delta, rate, acc, axis, vel, accel, R_new, v, a):
    """`with_swing_pitch` for one foot: its rotation ``R`` turned by ``delta`` about its own lateral axis (``axis``
    empty) or about the world ``axis`` (unit, (3,)), into ``R_new``; ``v_w += y rate``, ``a_w += y acc + (omega x
    y) rate`` with y that axis, into ``v`` and ``a`` (one compiled call for a tick's few numbers)."""
    c, s = math.cos(delta), math.sin(delta)
    if axis.shape[0] == 0:  # R_new = R Ry(delta)
        for i in range(3):
            r0, r1, r2 = R[i, 0], R[i, 1], R[i, 2]
            R_new[i, 0] = r0 * c + r2 * -s
            R_new[i, 1] = r1
            R_new[i, 2] = r0 * s + r2 * c
        yx, yy, yz = R[0, 1], R[1, 1], R[2, 1]
    else:  # R_new = Rot(axis, delta) R = (I + s K + (1 - c) K^2) R
        yx, yy, yz = axis[0], axis[1], axis[2]
        K = np.array([[0.0, -yz, yy], [yz, 0.0, -yx], [-yy, yx, 0.0]])
        K2 = K @ K
        Q = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                Q[i, j] = (1.0 if i == j else 0.0) + s * K[i, j] + (1.0 - c) * K2[i, j]
        for i in range(3):
            for j in range(3):
                R_new[i, j] = Q[i, 0] * R[0, j] + Q[i, 1] * R[1, j] + Q[i, 2] * R[2, j]
    wx, wy, wz = vel[3], vel[4], vel[5]
    v[0], v[1], v[2] = vel[0], vel[1], vel[2]
    v[3], v[4], v[5] = wx + yx * rate, wy + yy * rate, wz + yz * rate
    a[0], a[1], a[2] = accel[0], accel[1], accel[2]
    a[3] = accel[3] + (yx * acc + (wy * yz - wz * yy) * rate)
    a[4] = accel[4] + (yy * acc + (wz * yx - wx * yz) * rate)
    a[5] = accel[5] + (yz * acc + (wx * yy - wy * yx) * rate)


class TaskReferences:
    """Hands references to tasks: the CoM plan to every CoM task, each named target to the task of that name
    (unknown names are ignored: a scenario may serve several controllers), each swing-foot reference to the
    free-motion task of that foot. A pose reference without a rotation keeps the task's current one; a
    `JointReference` goes to a posture task.
    `swing_pitch` (the task set's `swing_foot.pitch_with_leg`): the swing feet's references take the plan's pitch
    offsets (`References.swing_pitch`, `with_swing_pitch`)."""

    def __init__(self, tasks: Sequence[Task], free_tasks: Mapping[Side, FrameTask], swing_pitch: bool = False):
        self.com_tasks = tuple(t for t in tasks if isinstance(t, CoMTask))
        self.by_name = {t.name: t for t in tasks}
        self.free_tasks = dict(free_tasks)
        self.swing_pitch = bool(swing_pitch)

    def apply(self, refs: References, pitch_axes: Mapping | None = None) -> None:
        """Hand this tick's references to the tasks; `pitch_axes`: per side, a world axis to turn a swing foot's
        pitch about instead of its own lateral one (`with_swing_pitch`)."""
        com = refs.com
        if com is not None:
            first = None
            for task in self.com_tasks:
                if first is not None and type(task) is CoMTask:  # the same checked arrays, not checked again
                    task.share_reference(first)
                    continue
                task.set_reference(com.position, com.velocity, com.acceleration)
                if first is None and type(task) is CoMTask:
                    first = task
        for name, target in refs.targets.items():
            task = self.by_name.get(name)
            if task is None:
                continue
            if type(target) is JointReference:  # a posture task's joint-space reference
                task.set_reference(target.configuration, target.velocity, target.acceleration)
            else:
                task.set_pose(target.position, target.rotation, target.velocity, target.acceleration)
        feet = refs.feet
        if self.swing_pitch and refs.swing_pitch:  # the plan's swing that pitches with the leg
            feet = with_swing_pitch(feet, refs.swing_pitch, pitch_axes)
        for side, foot in feet.items():
            self.free_tasks[side].set_pose(foot.position, foot.rotation, foot.velocity, foot.acceleration)
