"""SE(3) task on a frame, in the LOCAL_WORLD_ALIGNED frame (origin on the frame, axes of the world)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.tasks import _validation as val
from wbcbench.tasks.exceptions import ReferenceNotSetError, TaskConfigError
from wbcbench.tasks.task import Task

__all__ = ["FrameTask"]

FloatArray = npt.NDArray[np.float64]

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_F64 = np.dtype(np.float64)


class FrameTask(Task):
    """Track a reference pose ``T_world_ref`` with frame ``frame``; 6 axes ``x y z roll pitch yaw``.

    All quantities are in LOCAL_WORLD_ALIGNED: velocity ``[p_dot; omega]`` with ``p_dot`` the velocity of the
    frame origin and ``omega`` the angular velocity, both in world axes (m/s, rad/s).

    * error ``e = [p_ref - p; log3(R_ref R^T)]`` (m, rad): the rotation error is the world-axes rotation
      vector taking the current orientation to the reference (``R_ref = exp(e_rot) R``); for small errors
      ``d e/dt = -J v`` (exactly, ``d e_rot/dt = -Jlog3(R_ref R^T) omega``). Roll, pitch, yaw name the
      components of this rotation vector along world x, y, z, not Euler angles.
    * jacobian: ``pin.getFrameJacobian(..., LOCAL_WORLD_ALIGNED)``;
    * drift: the classical acceleration ``[p_ddot; omega_dot]`` at zero joint acceleration
      (``pin.getFrameClassicalAcceleration(..., LOCAL_WORLD_ALIGNED)``; the spatial acceleration would be wrong
      here by ``omega x p_dot``), which is ``d/dt (J v)`` at constant ``v``.

    A mask ``(0, 0, 0, 1, 1, 1)`` gives an orientation-only task (waist), ``(1, 1, 1, 0, 0, 0)`` a
    position-only one.

    Args:
        model: robot model (only read at construction to resolve the frame).
        frame: frame name, e.g. ``"torso_2_link"``.
        name: task name; defaults to the frame name.
        weight, kp, kd, mask: see :class:`~wbcbench.tasks.task.Task` (gains per axis x y z roll pitch yaw).

    Raises:
        UnknownNameError: ``frame`` is not in the model (the message lists close names).
        TaskConfigError: invalid gain, mask or weight.
    """

    AXES = ("x", "y", "z", "roll", "pitch", "yaw")
    UNITS = ("m", "m", "m", "rad", "rad", "rad")

    yaml_type = "frame"

    @classmethod
    def parse_options(cls, sec: Any, robot: Any) -> dict:
        """`frame`: a model frame name or a symbolic one of the robot profile (`base`, `torso`, `head`,
        `left_hand`, `right_hand`, `left_foot`, `right_foot`)."""
        from wbcbench.errors import UnknownNameError
        from wbcbench.tasks.registry import resolve_frame

        frame = resolve_frame(robot, sec.str("frame"))
        if not robot.model.existFrame(frame):
            raise UnknownNameError("frame", frame, [f.name for f in robot.model.frames], file=sec.file,
                                   key=sec.key("frame"))
        return {"frame": frame}

    @classmethod
    def axes(cls, robot: Any, options: dict) -> int:
        return 6

    @classmethod
    def from_spec(cls, robot: Any, spec: Any) -> FrameTask:
        return cls(robot.model, spec.options["frame"], name=spec.name, weight=spec.weight, kp=spec.kp, kd=spec.kd,
                   mask=spec.mask)

    def __init__(
        self,
        model: pin.Model,
        frame: str,
        *,
        kp: Any,
        kd: Any = None,
        weight: float = 1.0,
        mask: Sequence[bool | int] | None = None,
        name: str | None = None,
    ) -> None:
        owner_name = frame if name is None else name
        self._frame_id = val.find_frame(model, frame, f"{type(self).__name__} {owner_name!r}")
        self._frame = frame
        super().__init__(
            name=owner_name, axis_names=self.AXES, units=self.UNITS, weight=weight, kp=kp, kd=kd, mask=mask
        )
        self._p_ref: FloatArray | None = None
        self._R_ref: FloatArray | None = None
        self._error_kind: tuple = (None, None)  # (rows, part of the error they select), see _write_error

    @property
    def frame(self) -> str:
        """Name of the controlled frame."""
        return self._frame

    @property
    def frame_id(self) -> int:
        """Index of the controlled frame in the model."""
        return self._frame_id

    # ---------------------------------------------------------------------------------------- references
    def set_reference(
        self,
        pose: pin.SE3,
        velocity: npt.ArrayLike | None = None,
        acceleration: npt.ArrayLike | None = None,
    ) -> None:
        """Set the reference for this tick.

        Args:
            pose: ``T_world_ref``, the reference placement of the frame in the world.
            velocity: ``[p_dot; omega]`` reference, (6,), m/s and rad/s in world axes; ``None`` for zero.
            acceleration: ``[p_ddot; omega_dot]`` reference, (6,), m/s^2 and rad/s^2; ``None`` for zero.
        """
        if not isinstance(pose, pin.SE3):
            raise TaskConfigError(self.owner, "pose", f"expected a pinocchio.SE3, got {type(pose).__name__}")
        p = val.as_vector(pose.translation, 3, self.owner, "pose.translation")
        R = np.array(pose.rotation, dtype=np.float64)
        if not val.is_rotation(R):
            raise TaskConfigError(self.owner, "pose.rotation", "expected a rotation matrix (R^T R = I)")
        derivatives = self._check_derivatives(velocity, acceleration)
        self._store_derivatives(derivatives)
        self._p_ref = val.frozen(p)
        self._R_ref = val.frozen(R)

    def set_pose(
        self,
        position: npt.ArrayLike,
        rotation: npt.ArrayLike | None,
        velocity: npt.ArrayLike | None = None,
        acceleration: npt.ArrayLike | None = None,
    ) -> None:
        """:meth:`set_reference` from a position (3,) and a rotation matrix (3, 3) instead of an SE3, with the
        same checks; float64 arrays of those shapes (what `PoseReference` holds) are checked and copied in one
        compiled call (a reference is set every tick). ``rotation`` None holds the reference's current one (a
        `PoseReference` that only translates)."""
        if rotation is None:
            rotation = self._R_ref
            if rotation is None:
                raise ReferenceNotSetError(f"{self.owner}: no orientation to hold before a first set_reference")
        if (type(rotation) is np.ndarray and rotation.dtype == _F64 and rotation.shape == (3, 3)
                and val.is_vector(position, 3) and (velocity is None or val.is_vector(velocity, 6))
                and (acceleration is None or val.is_vector(acceleration, 6))):
            p, R = np.empty(3), np.empty((3, 3))
            v = self._zero_reference() if velocity is None else np.empty(6)
            a = self._zero_reference() if acceleration is None else np.empty(6)
            E = val.EMPTY
            if val.copy_pose_checked(position, rotation, E if velocity is None else velocity,
                                     E if acceleration is None else acceleration, p, R, E if velocity is None else v,
                                     E if acceleration is None else a):
                self._v_ref = v if velocity is None else val.frozen(v)
                self._a_ref = a if acceleration is None else val.frozen(a)
                self._p_ref = val.frozen(p)
                self._R_ref = val.frozen(R)
                return
        # anything else, or a check failed: the general path (and its error message)
        self.set_reference(pin.SE3(np.asarray(rotation, dtype=np.float64), np.asarray(position, dtype=np.float64)),
                           velocity, acceleration)

    def set_reference_to_current(self, model: pin.Model, data: pin.Data) -> None:
        """Set the reference pose to the current pose of the frame, with zero velocity and acceleration."""
        self.set_reference(self.placement(model, data))

    @property
    def reference(self) -> pin.SE3 | None:
        """The reference pose ``T_world_ref`` (a copy), or ``None`` before the first ``set_reference``."""
        if self._R_ref is None or self._p_ref is None:
            return None
        return pin.SE3(self._R_ref.copy(), self._p_ref.copy())

    # ------------------------------------------------------------------------------------------- contract
    def placement(self, model: pin.Model, data: pin.Data) -> pin.SE3:
        """Current placement ``T_world_frame`` (a copy)."""
        return pin.SE3(pin.updateFramePlacement(model, data, self._frame_id))

    def error(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``[p_ref - p; log3(R_ref R^T)]``, (6,), m and rad in world axes."""
        if self._R_ref is None or self._p_ref is None:
            raise ReferenceNotSetError(f"{self.owner}: call set_reference before evaluating the task")
        oMf = pin.updateFramePlacement(model, data, self._frame_id)
        e = np.empty(6)
        e[:3] = self._p_ref - oMf.translation
        e[3:] = pin.log3(self._R_ref @ oMf.rotation.T)
        return e

    def _write_error(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        """Stacked evaluation (see Task._write_error): only the translation or rotation part when the mask
        selects only that part."""
        rows, kind = self._error_kind
        if rows is not self._rows:  # the mask changed: which part of the error it selects
            sel = self._selection
            kind = ("all" if self._all_selected else "other" if type(sel) is not slice
                    else "rotation" if sel == slice(3, 6) else "translation" if sel == slice(0, 3) else "other")
            self._error_kind = (self._rows, kind)
        if kind == "other":
            super()._write_error(model, data, out)
            return
        if self._R_ref is None or self._p_ref is None:
            raise ReferenceNotSetError(f"{self.owner}: call set_reference before evaluating the task")
        oMf = pin.updateFramePlacement(model, data, self._frame_id)
        if kind == "rotation":
            out[:] = pin.log3(self._R_ref @ oMf.rotation.T)
        elif kind == "all":
            out[:3] = self._p_ref - oMf.translation
            out[3:] = pin.log3(self._R_ref @ oMf.rotation.T)
        else:
            np.subtract(self._p_ref, oMf.translation, out=out)

    def jacobian(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """LOCAL_WORLD_ALIGNED frame Jacobian, (6, nv)."""
        return pin.getFrameJacobian(model, data, self._frame_id, _LWA)

    def velocity(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``[p_dot; omega]``, (6,), m/s and rad/s in world axes."""
        return pin.getFrameVelocity(model, data, self._frame_id, _LWA).vector

    def drift(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Classical acceleration ``[p_ddot; omega_dot]`` at zero joint acceleration, (6,), world axes."""
        return pin.getFrameClassicalAcceleration(model, data, self._frame_id, _LWA).vector

