"""Joint posture task over actuated joints, references in configuration space."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.tasks import _validation as val
from wbcbench.tasks.exceptions import ReferenceNotSetError, TaskConfigError
from wbcbench.tasks.task import Task

__all__ = ["PostureTask"]

FloatArray = npt.NDArray[np.float64]


def _unit(joint_type: str) -> str:
    """Unit of a joint's velocity coordinates integrated once: m for prismatic joints, rad otherwise."""
    return (
        "m"
        if joint_type in ("JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned")
        else "rad"
    )


_SUBTRACTION_JOINTS = frozenset({
    "JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned",
    "JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned",
})
"""Joints whose ``pin.difference`` is ``q1 - q0`` on their single coordinate (bounded revolute, prismatic)."""


class PostureTask(Task):
    """Track a reference configuration ``q_ref`` on a set of actuated joints.

    The task space is the tangent space of the selected joints: one axis per velocity coordinate (one per
    revolute joint), in the order of ``joints``.

    * error ``pin.difference(q, q_ref)`` restricted to the selected velocity coordinates (rad for revolute
      joints; ``q_ref (-) q``, so continuous, spherical, ... joints are handled by the Lie group);
    * jacobian: the constant selection matrix ``S`` (dim, nv) with ``S v = v[joints]``; drift: zero.

    Args:
        model: robot model.
        joints: joint names; ``None`` selects every joint except a floating root (free-flyer or planar joint
            attached to the universe), in model order. A floating root cannot be selected.
        kp, kd: scalar, one value per axis (dim,), or a mapping ``{joint name: gain}`` covering exactly the
            selected joints (a joint with several velocity coordinates gets the same gain on each).
        weight, mask: see :class:`~wbcbench.tasks.task.Task` (one mask entry per axis).
        name: task name.

    Raises:
        UnknownNameError: a joint name is not in the model (the message lists close names).
        TaskConfigError: floating root or duplicate joint, invalid gain, mask or weight.
    """

    _constant_jacobian = True

    yaml_type = "posture"
    per_joint_gains = True
    maskable = False

    @classmethod
    def axes(cls, robot: Any, options: dict) -> int:
        return robot.na

    @classmethod
    def from_spec(cls, robot: Any, spec: Any) -> PostureTask:
        return cls(robot.model, name=spec.name, weight=spec.weight, kp=spec.kp, kd=spec.kd, joints=robot.joint_names)

    def reset_reference(self, model: pin.Model, data: pin.Data, q_reference: FloatArray) -> None:
        self.set_reference(q_reference)

    def __init__(
        self,
        model: pin.Model,
        *,
        kp: Any,
        kd: Any = None,
        weight: float = 1.0,
        joints: Sequence[str] | None = None,
        mask: Sequence[bool | int] | None = None,
        name: str = "posture",
    ) -> None:
        owner = f"{type(self).__name__} {name!r}"
        if joints is None:
            joint_ids = [j for j in range(1, model.njoints) if not val.is_floating_root(model, j)]
        else:
            if isinstance(joints, str):
                raise TaskConfigError(
                    owner, "joints", f"expected a sequence of joint names, got the string {joints!r}"
                )
            joint_ids = []
            for joint in joints:
                j = val.find_joint(model, joint, owner)
                if val.is_floating_root(model, j):
                    raise TaskConfigError(owner, "joints", f"{joint!r} is a floating root joint, not actuated")
                if j in joint_ids:
                    raise TaskConfigError(owner, "joints", f"{joint!r} is listed twice")
                joint_ids.append(j)
        if not joint_ids:
            raise TaskConfigError(owner, "joints", "selects no joint")
        self._joint_ids = tuple(joint_ids)
        self._joint_names = tuple(model.names[j] for j in joint_ids)
        idx: list[int] = []
        axis_names: list[str] = []
        self._joint_axes: dict[str, list[int]] = {}
        for j, jname in zip(self._joint_ids, self._joint_names, strict=True):
            nv_j, idx_v = model.joints[j].nv, model.joints[j].idx_v
            self._joint_axes[jname] = list(range(len(idx), len(idx) + nv_j))
            idx.extend(range(idx_v, idx_v + nv_j))
            axis_names.extend([jname] if nv_j == 1 else [f"{jname}[{k}]" for k in range(nv_j)])
        self._idx_v = val.frozen(np.array(idx, dtype=np.intp))
        self._nq, self._nv = model.nq, model.nv
        units = [_unit(model.joints[j].shortname()) for j in self._joint_ids for _ in range(model.joints[j].nv)]
        super().__init__(name=name, axis_names=axis_names, units=units, weight=weight, kp=kp, kd=kd, mask=mask)
        S = np.zeros((len(idx), model.nv))
        S[np.arange(len(idx)), self._idx_v] = 1.0
        self._S = val.frozen(S)
        self._zero = val.frozen(np.zeros(len(idx)))
        self._neutral = pin.neutral(model)
        unselected = np.ones(model.nq, dtype=bool)
        for j in self._joint_ids:
            unselected[model.joints[j].idx_q : model.joints[j].idx_q + model.joints[j].nq] = False
        self._unselected_q = unselected
        self._model = model  # only for Lie-group checks of q_ref; never mutated
        self._q_ref: FloatArray | None = None
        # joints whose Lie-group difference is a subtraction (1-dof revolute and prismatic): the stacked error
        # reads q directly (same numbers as pin.difference); None when a selected joint is of another kind
        vector_space = all(model.joints[j].shortname() in _SUBTRACTION_JOINTS for j in self._joint_ids)
        self._idx_q_axes = (
            np.array([model.joints[j].idx_q for j in self._joint_ids], dtype=np.intp) if vector_space else None
        )
        self._error_index: tuple = (None, None, None)  # (rows, index into q or v, (q_ref, its selection, data, q's))

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Selected joints, in task order."""
        return self._joint_names

    @property
    def velocity_indices(self) -> npt.NDArray[np.intp]:
        """Indices in ``v`` of the task axes, (dim,), read-only."""
        return self._idx_v

    def _gain(self, value: Any, key: str) -> FloatArray:
        if isinstance(value, Mapping):
            missing = [j for j in self._joint_names if j not in value]
            unknown = [str(k) for k in value if k not in self._joint_axes]
            if missing or unknown:
                raise TaskConfigError(
                    self.owner,
                    key,
                    f"a per-joint mapping must cover exactly the task joints; missing {missing}, "
                    f"not in the task {unknown}",
                )
            gains = np.empty(self.dim)
            for jname, axes in self._joint_axes.items():
                gains[axes] = val.as_scalar(value[jname], self.owner, f"{key}[{jname!r}]")
            value = gains
        return super()._gain(value, key)

    # ---------------------------------------------------------------------------------------- references
    def set_reference(
        self,
        q_ref: npt.ArrayLike,
        velocity: npt.ArrayLike | None = None,
        acceleration: npt.ArrayLike | None = None,
    ) -> None:
        """Set the reference for this tick.

        Args:
            q_ref: full reference configuration (nq,) (e.g. the SRDF half-sitting); only the selected
                joints are used (the others, including the base, may hold anything finite).
            velocity: reference joint velocities of the task axes (dim,) [rad/s]; ``None`` for zero.
            acceleration: reference joint accelerations of the task axes (dim,) [rad/s^2]; ``None`` for zero.
        """
        q = val.as_vector(q_ref, self._nq, self.owner, "q_ref")
        q[self._unselected_q] = self._neutral[self._unselected_q]
        if not pin.isNormalized(self._model, q, 1e-6):
            raise TaskConfigError(self.owner, "q_ref", "the selected joints' configuration is not normalized")
        derivatives = self._check_derivatives(velocity, acceleration)
        self._store_derivatives(derivatives)
        self._q_ref = val.frozen(q)

    def set_reference_to_current(self, model: pin.Model, data: pin.Data) -> None:
        """Set the reference to the current configuration ``data.q_in``, with zero velocity and acceleration."""
        self.set_reference(np.array(data.q_in))

    @property
    def reference(self) -> FloatArray | None:
        """Stored reference configuration (nq,), read-only (unselected joints set to neutral), or ``None``."""
        return self._q_ref

    # ------------------------------------------------------------------------------------------- contract
    def error(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``q_ref (-) q`` on the task axes, (dim,) [rad]."""
        if self._q_ref is None:
            raise ReferenceNotSetError(f"{self.owner}: call set_reference before evaluating the task")
        return pin.difference(model, data.q_in, self._q_ref)[self._idx_v]

    def jacobian(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Constant selection matrix (dim, nv), read-only."""
        return self._S

    def velocity(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Joint velocities of the task axes, (dim,) [rad/s]."""
        return data.v_in[self._idx_v]

    def drift(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Zero (dim,), read-only: joint coordinates have no drift."""
        return self._zero

    # stacked evaluation (see Task._write_jacobian)
    def _write_error(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        q_ref = self._q_ref
        if q_ref is None:
            raise ReferenceNotSetError(f"{self.owner}: call set_reference before evaluating the task")
        rows, idx, ref = self._error_index
        if rows is self._rows and ref is not None and ref[0] is q_ref and ref[2] is data:
            # the usual tick: the reference's selection and a view of data.q_in (pinocchio's fixed-size buffer,
            # filled in place by every kinematics update) kept from the last call
            np.subtract(ref[1], ref[3], out=out)
            return
        if rows is not self._rows:  # first call, or the mask changed: where the selected axes are
            if self._idx_q_axes is None:
                idx = self._idx_v if self._all_selected else self._idx_v[self._rows]
            else:
                iq = self._idx_q_axes if self._all_selected else self._idx_q_axes[self._rows]
                contiguous = iq.size and iq[-1] - iq[0] + 1 == iq.size
                idx = slice(int(iq[0]), int(iq[-1]) + 1) if contiguous else iq
            ref = None
        if self._idx_q_axes is None:
            self._error_index = (self._rows, idx, None)
            np.take(pin.difference(model, data.q_in, q_ref), idx, out=out)
            return
        q_sel = data.q_in[idx]
        # a new reference (set_reference stores a new array) or data: its selection, and the view of q (None when
        # the selection is not one slice: a copy)
        ref = (q_ref, q_ref[idx], data if type(idx) is slice else None, q_sel)
        self._error_index = (self._rows, idx, ref)
        np.subtract(ref[1], q_sel, out=out)

    def _write_drift(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        out.fill(0.0)
