"""Centroidal angular momentum task (regularisation towards a target, zero by default)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.tasks import _validation as val
from wbcbench.tasks.exceptions import TaskConfigError
from wbcbench.tasks.task import Task

__all__ = ["AngularMomentumTask"]

FloatArray = npt.NDArray[np.float64]


class AngularMomentumTask(Task):
    """Regulate the centroidal angular momentum ``h_ang`` (about the CoM, world axes, kg m^2/s).

    The momentum ``h_ang = Ag_ang v`` is a velocity-level quantity with no configuration behind it, so in the
    shared formulation its position error is identically zero, its "velocity" ``J v`` is the momentum and its
    velocity reference ``v_ref`` is the target momentum. The regulation gain is therefore the derivative gain
    ``kd`` (1/s) of the formulation, and ``kp`` is fixed to zero:

    * acceleration level: ``Ag_ang dv = dh_ref + kd (h_ref - h_ang) - dAg_ang v``; with the default target
      ``h_ref = dh_ref = 0`` this is ``b = -kd h_ang - dAg_ang v`` (paper 000 Eq. 5 and Table 1, where the gain
      is called K_p,am = 10 for both TSID controllers: pass it as ``kd``);
    * velocity level: ``Ag_ang v = h_ref``.

    Jacobian: ``data.Ag[3:]`` (3, nv); velocity: ``data.hg.angular``; drift: ``data.dAg[3:] v``.

    Args:
        model: robot model (unused apart from signature symmetry with the other tasks).
        kd: regulation gain on the momentum error, scalar or (3,), 1/s (the paper's K_p,am).
        weight, mask: see :class:`~wbcbench.tasks.task.Task` (axes Lx Ly Lz).
        name: task name.

    Raises:
        TaskConfigError: invalid gain, mask or weight; any non-zero ``kp``.
    """

    AXES = ("Lx", "Ly", "Lz")
    UNITS = ("kg m^2/s", "kg m^2/s", "kg m^2/s")

    yaml_type = "angular_momentum"

    @classmethod
    def axes(cls, robot: Any, options: dict) -> int:
        return 3

    @classmethod
    def from_spec(cls, robot: Any, spec: Any) -> AngularMomentumTask:
        # the paper's "Kp am" is the rate gain of dh = -Kp h: the task's kd
        return cls(robot.model, name=spec.name, weight=spec.weight, kd=spec.kp, mask=spec.mask)

    def reset_reference(self, model: pin.Model, data: pin.Data, q_reference: FloatArray) -> None:
        self.set_reference()

    def __init__(
        self,
        model: pin.Model,
        *,
        kd: Any,
        weight: float = 1.0,
        mask: Sequence[bool | int] | None = None,
        name: str = "angular_momentum",
    ) -> None:
        super().__init__(
            name=name, axis_names=self.AXES, units=self.UNITS, weight=weight, kp=0.0, kd=kd, mask=mask
        )
        self._zero = val.frozen(np.zeros(3))
        self._views: tuple | None = None

    def _gain(self, value: Any, key: str) -> FloatArray:
        gain = super()._gain(value, key)
        if key == "kp" and np.any(gain != 0.0):
            raise TaskConfigError(
                self.owner,
                "kp",
                f"the momentum has no position error; set its regulation gain as kd, got kp={value!r}",
            )
        return gain

    def set_reference(self, momentum: npt.ArrayLike | None = None, rate: npt.ArrayLike | None = None) -> None:
        """Set the target angular momentum (3,) [kg m^2/s] and its rate (3,) [N m]; ``None`` for zero."""
        self._store_derivatives(self._check_derivatives(momentum, rate))

    @property
    def reference(self) -> FloatArray:
        """Target angular momentum (3,) [kg m^2/s], read-only (same array as ``v_ref``)."""
        return self.v_ref

    def error(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Zero (3,), read-only: the momentum has no position-level error."""
        return self._zero

    def jacobian(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Angular part of the centroidal momentum matrix, (3, nv) [kg m^2 per unit of v]."""
        return np.array(data.Ag[3:])

    def velocity(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Current centroidal angular momentum (3,) [kg m^2/s]."""
        return np.array(data.hg.angular)

    def drift(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """``dAg_ang v``: momentum rate at zero joint acceleration (3,) [N m]."""
        return data.dAg[3:] @ data.v_in

    # stacked evaluation (see Task._write_jacobian): only the selected axes, no temporaries
    def _data_views(self, data: pin.Data) -> tuple:
        """(data, rows, Ag, dAg): the angular rows of pinocchio's centroidal buffers restricted to the selected
        axes, kept between ticks (fixed-size buffers of ``data``, which the tuple keeps alive); copies when the
        selection is not a slice."""
        views = self._views
        if views is None or views[0] is not data or views[1] is not self._rows:
            sel = self._selection
            views = (data, self._rows, data.Ag[3:][sel], data.dAg[3:][sel])
            if type(sel) is not slice:  # fancy indexing copied: nothing to keep
                return views
            self._views = views
        return views

    def _write_jacobian(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        out[...] = self._data_views(data)[2]

    def _write_error(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        out.fill(0.0)

    def _write_drift(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        np.matmul(self._data_views(data)[3], data.v_in, out=out)
