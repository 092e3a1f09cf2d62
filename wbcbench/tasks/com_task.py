"""Centre-of-mass task (3 axes, world frame)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.tasks import _validation as val
from wbcbench.tasks.exceptions import ReferenceNotSetError
from wbcbench.tasks.task import Task

__all__ = ["CoMTask"]

FloatArray = npt.NDArray[np.float64]


class CoMTask(Task):
    """Track a reference CoM position ``p_world_com`` (m, world axes x y z).

    * error ``p_ref - p_com`` (m), from ``data.com[0]``;
    * jacobian ``Ag[:3] / m`` (= ``Jcom``; read from the centroidal map so that both kinematics updates
      provide it);
    * velocity ``data.vcom[0]``; drift ``dAg[:3] v / m`` (the CoM acceleration at zero joint acceleration).

    Use the mask to split the CoM into separate tasks with their own gains and weights, e.g.
    ``CoMTask(model, name="com_height", mask=(0, 0, 1), ...)`` and ``CoMTask(model, name="com_xy",
    mask=(1, 1, 0), ...)``.

    Args:
        model: robot model (its total mass is read at construction).
        name: task name.
        weight, kp, kd, mask: see :class:`~wbcbench.tasks.task.Task` (per axis x y z).
    """

    AXES = ("x", "y", "z")
    UNITS = ("m", "m", "m")

    yaml_type = "com"

    @classmethod
    def axes(cls, robot: Any, options: dict) -> int:
        return 3

    @classmethod
    def from_spec(cls, robot: Any, spec: Any) -> CoMTask:
        return cls(robot.model, name=spec.name, weight=spec.weight, kp=spec.kp, kd=spec.kd, mask=spec.mask)

    def __init__(
        self,
        model: pin.Model,
        *,
        kp: Any,
        kd: Any = None,
        weight: float = 1.0,
        mask: Sequence[bool | int] | None = None,
        name: str = "com",
    ) -> None:
        super().__init__(name=name, axis_names=self.AXES, units=self.UNITS, weight=weight, kp=kp, kd=kd, mask=mask)
        self._mass = float(pin.computeTotalMass(model))
        self._inv_mass = 1.0 / self._mass
        self._p_ref: FloatArray | None = None
        self._views: tuple | None = None

    @property
    def mass(self) -> float:
        """Total mass of the model [kg]."""
        return self._mass

    def set_reference(
        self,
        position: npt.ArrayLike,
        velocity: npt.ArrayLike | None = None,
        acceleration: npt.ArrayLike | None = None,
    ) -> None:
        """Set the reference for this tick: ``p_world_com`` (3,) [m], velocity (3,) [m/s] and acceleration (3,)
        [m/s^2] (``None``: zero). All three components are stored even when the mask drops some."""
        if (val.is_vector(position, 3) and (velocity is None or val.is_vector(velocity, 3))
                and (acceleration is None or val.is_vector(acceleration, 3))):
            # float64 arrays (what a `PointReference` holds): checked and copied in one compiled call into the
            # rows of one new array, made read-only once
            E = val.EMPTY
            pva = np.empty((3, 3))
            if val.copy_rows_finite(position, E if velocity is None else velocity,
                                    E if acceleration is None else acceleration, pva):
                pva.setflags(write=False)
                self._p_ref = pva[0]
                self._v_ref = self._zero_reference() if velocity is None else pva[1]
                self._a_ref = self._zero_reference() if acceleration is None else pva[2]
                return
        p = val.as_vector(position, 3, self.owner, "position")
        derivatives = self._check_derivatives(velocity, acceleration)
        self._store_derivatives(derivatives)
        self._p_ref = val.frozen(p)

    def share_reference(self, other: CoMTask) -> None:
        """Take the reference another CoM task was given at its last `set_reference` (the same read-only arrays:
        a plan's CoM handed to several CoM tasks, e.g. ``com_xy`` and ``com_z``, is checked and copied once)."""
        if other._p_ref is None:
            raise ReferenceNotSetError(f"{other.owner}: call set_reference before sharing its reference")
        self._p_ref, self._v_ref, self._a_ref = other._p_ref, other._v_ref, other._a_ref

    def set_reference_to_current(self, model: pin.Model, data: pin.Data) -> None:
        """Set the reference to the current CoM position, with zero velocity and acceleration."""
        self.set_reference(self.position(model, data))

    @property
    def reference(self) -> FloatArray | None:
        """Reference CoM position (3,) [m], read-only, or ``None`` before the first ``set_reference``."""
        return self._p_ref

    def position(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Current CoM position ``p_world_com`` (3,) [m] (a copy)."""
        return np.array(data.com[0])

    def error(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``p_ref - p_com`` (3,) [m]."""
        if self._p_ref is None:
            raise ReferenceNotSetError(f"{self.owner}: call set_reference before evaluating the task")
        return self._p_ref - data.com[0]

    def jacobian(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """CoM Jacobian (3, nv)."""
        return data.Ag[:3] * self._inv_mass

    def velocity(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """CoM velocity (3,) [m/s]."""
        return np.array(data.vcom[0])

    def drift(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """CoM acceleration at zero joint acceleration (3,) [m/s^2]."""
        return (data.dAg[:3] @ data.v_in) * self._inv_mass

    # stacked evaluation (see Task._write_jacobian): only the selected axes, no temporaries
    def _data_views(self, data: pin.Data) -> tuple | None:
        """(data, rows, Ag, dAg, com) with the last three views of pinocchio's buffers restricted to the selected
        axes, kept between ticks (``data.Ag``, ``data.dAg`` and ``data.com[0]`` are fixed-size buffers of ``data``,
        which the tuple keeps alive); None when the selection is not a slice (indexing would copy)."""
        views = self._views
        if views is not None and views[0] is data and views[1] is self._rows:
            return views
        sel = self._selection
        if type(sel) is not slice:
            return None
        self._views = views = (data, self._rows, data.Ag[sel], data.dAg[sel], data.com[0][sel])
        return views

    def _write_jacobian(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        views = self._data_views(data)
        np.multiply(data.Ag[self._selection] if views is None else views[2], self._inv_mass, out=out)

    def _write_error(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        if self._p_ref is None:
            raise ReferenceNotSetError(f"{self.owner}: call set_reference before evaluating the task")
        sel = self._selection
        views = self._data_views(data)
        np.subtract(self._p_ref[sel], data.com[0][sel] if views is None else views[4], out=out)

    def _write_drift(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        views = self._data_views(data)
        np.matmul(data.dAg[self._selection] if views is None else views[3], data.v_in, out=out)
        out *= self._inv_mass
