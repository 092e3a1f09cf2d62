"""The two shared formulations that turn any task into rows ``(A, b)``.

Written once for every task (frame, CoM, posture, angular momentum, contact motion): a task only supplies its
error ``e``, Jacobian ``J``, velocity ``J v`` and drift ``J_dot v`` in its own space, plus references and
per-axis gains; the formulations apply the control law and the mask. Weights and priority levels are left to
the caller (the QP formulation).

Acceleration level (inverse dynamics, decision variable ``dv``), paper 000 Eq. 9 with ``e = x* (-) x``::

    J dv = a_ref + Kd (v_ref - J v) + Kp e - J_dot v

Velocity level (IK, decision variable ``v``; ``Kp`` in 1/s, no time step involved)::

    J v = v_ref + Kp e

For the angular momentum task the error is identically zero and ``v_ref`` is the target momentum, so these
become ``Ag_ang dv = dh_ref + Kd (h_ref - h) - dAg_ang v`` and ``Ag_ang v = h_ref``.
"""

from __future__ import annotations

import pinocchio as pin

from wbcbench.tasks.rows import Rows
from wbcbench.tasks.task import Task

__all__ = ["acceleration_rows", "velocity_rows"]


def acceleration_rows(task: Task, model: pin.Model, data: pin.Data) -> Rows:
    """Rows ``J dv = a_ref + Kd (v_ref - J v) + Kp e - J_dot v`` over the axes selected by the task mask.

    Requires :func:`~wbcbench.tasks.kinematics.update_kinematics` for the current ``(q, v)``.

    Returns:
        ``Rows(A (m, nv), b (m,))``, b in task units / s^2 (m/s^2, rad/s^2, N m/s for momentum).
    """
    J = task.jacobian(model, data)
    b = task.a_ref + task.kd * (task.v_ref - task.velocity(model, data)) + task.kp * task.error(model, data)
    b -= task.drift(model, data)
    if task.all_selected:
        return Rows(J, b)
    rows = task.selection
    return Rows(J[rows], b[rows])


def velocity_rows(task: Task, model: pin.Model, data: pin.Data) -> Rows:
    """Rows ``J v = v_ref + Kp e`` over the axes selected by the task mask.

    Requires :func:`~wbcbench.tasks.kinematics.update_kinematics_velocity_level` (or the acceleration-level
    update) for the current ``q``. With a time step ``dt``, ``Kp dt <= 1`` avoids overshooting the reference
    in one step.

    Returns:
        ``Rows(A (m, nv), b (m,))``, b in task units / s (m/s, rad/s, N m s for momentum).
    """
    J = task.jacobian(model, data)
    b = task.v_ref + task.kp * task.error(model, data)
    if task.all_selected:
        return Rows(J, b)
    rows = task.selection
    return Rows(J[rows], b[rows])
