"""The contract every task fulfils, in its own task space of dimension ``dim``.

A task is a function ``x(q)`` of the configuration (frame pose, CoM, joint positions), or for momentum tasks a
quantity ``J(q) v`` linear in the velocity. It provides, after the kinematics update of the tick
(:mod:`wbcbench.tasks.kinematics`):

* ``error(model, data)``: ``e = x* (-) x`` (reference minus current, on the task's manifold), shape (dim,);
* ``jacobian(model, data)``: ``J`` with ``x_dot = J v``, shape (dim, nv);
* ``velocity(model, data)``: ``J v``, shape (dim,);
* ``drift(model, data)``: ``J_dot v``, the task acceleration at zero joint acceleration, shape (dim,);

and carries per-axis gains ``kp`` (1/s^2 at acceleration level, 1/s at velocity level) and ``kd`` (1/s),
reference velocity ``v_ref`` and acceleration ``a_ref`` (task units / s, / s^2), a row mask, a name and a weight.
:mod:`wbcbench.tasks.formulation` turns that into rows ``(A, b)``; weights and priorities are the business of
whoever assembles the QP. Gains, mask and weight can be changed at any time through validated setters
(e.g. per contact phase); references are set per tick with each task's ``set_reference``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.tasks import _validation as val

__all__ = ["Task"]

FloatArray = npt.NDArray[np.float64]


class Task(ABC):
    """Base class of all tasks (see the module docstring for the contract).

    Args:
        name: task name, unique within a controller (used in logs and error messages).
        axis_names: one name per task axis, e.g. ``("x", "y", "z", "roll", "pitch", "yaw")``; ``dim`` is its
            length.
        units: unit of the task quantity per axis, e.g. ``("m", "m", "m", "rad", "rad", "rad")``.
        weight: weight >= 0 in a weighted QP (dimensionless; relative to the other tasks of the same level).
        kp: proportional gain, scalar or one per axis, >= 0.
        kd: derivative gain, scalar or one per axis, >= 0; ``None`` means ``2 sqrt(kp)`` (critical damping).
        mask: ``dim`` booleans selecting the rows to emit; ``None`` selects all.

    Raises:
        TaskConfigError: on any invalid argument (the message names the task and the key).
    """

    _config_epoch: ClassVar[int] = 0
    """Incremented by every weight, gain or mask setter of any task, so that a :class:`~wbcbench.tasks.TaskStack`
    knows with one comparison per tick whether its cached layout (rows, gains, weights) is still valid."""

    _constant_jacobian: ClassVar[bool] = False
    """True when :meth:`jacobian` never changes (posture): a stack writes it once per layout, not per tick."""

    # ---- task-set YAML (see wbcbench.tasks.registry)
    yaml_type: ClassVar[str | None] = None
    """The `type:` of this task in task-set files (None: not available from YAML)."""

    per_joint_gains: ClassVar[bool] = False
    """Gains may be given per joint-name prefix (a mapping) instead of per axis (posture)."""

    maskable: ClassVar[bool] = True
    """A `mask:` key selects axes."""

    @classmethod
    def parse_options(cls, sec: Any, robot: Any) -> dict:
        """The type's own options from its task-set entry (a `wbcbench.config.Section`; read the keys with it,
        errors then name the file and key). Default: none."""
        return {}

    @classmethod
    def axes(cls, robot: Any, options: dict) -> int:
        """The number of axes of a task of this type with these options (the length of kp, kd and mask)."""
        raise NotImplementedError(f"{cls.__name__} does not say its number of axes")

    @classmethod
    def from_spec(cls, robot: Any, spec: Any) -> Task:
        """Build the task for `robot` (a `wbcbench.robots.Robot`) from its parsed `TaskSpec`."""
        raise NotImplementedError(f"{cls.__name__} cannot be built from a task set")

    def reset_reference(self, model: pin.Model, data: pin.Data, q_reference: FloatArray) -> None:
        """Set the reference a controller starts a run with (after `update_kinematics` at the initial state): by
        default where the task is now; posture tasks take `q_reference`, momentum tasks zero."""
        self.set_reference_to_current(model, data)

    def __init__(
        self,
        *,
        name: str,
        axis_names: Sequence[str],
        units: Sequence[str],
        weight: float,
        kp: Any,
        kd: Any,
        mask: Sequence[bool | int] | None,
    ) -> None:
        self._name = val.check_name(name, f"{type(self).__name__} {name!r}")
        self._axis_names = tuple(axis_names)
        self._units = tuple(units)
        self._dim = len(self._axis_names)
        self.weight = weight
        self.kp = kp
        self.kd = (2.0 * np.sqrt(self._kp)) if kd is None else kd
        self.mask = mask
        self._v_ref: FloatArray = val.frozen(np.zeros(self._dim))
        self._a_ref: FloatArray = val.frozen(np.zeros(self._dim))

    # ----------------------------------------------------------------------------------------------- contract
    @abstractmethod
    def error(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Task error ``e = x* (-) x`` (reference minus current), shape (dim,), in :attr:`units`."""

    @abstractmethod
    def jacobian(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Task Jacobian ``J`` (``x_dot = J v``), shape (dim, nv). May be read-only: copy before writing."""

    @abstractmethod
    def velocity(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Task velocity ``J v``, shape (dim,), in :attr:`units` per s. Needs the acceleration-level update."""

    @abstractmethod
    def drift(self, model: pin.Model, data: pin.Data) -> FloatArray:
        """Drift ``J_dot v``, shape (dim,), in :attr:`units` per s^2. Needs the acceleration-level update."""

    # ----------------------------------------------------------------------------------------- description
    @property
    def owner(self) -> str:
        """``"<Type> '<name>'"``, the prefix of every error message about this task."""
        return f"{type(self).__name__} {self._name!r}"

    @property
    def name(self) -> str:
        """Task name."""
        return self._name

    @property
    def dim(self) -> int:
        """Dimension of the task space before masking."""
        return self._dim

    @property
    def axis_names(self) -> tuple[str, ...]:
        """Name of each task axis, length :attr:`dim`."""
        return self._axis_names

    @property
    def units(self) -> tuple[str, ...]:
        """Unit of the task quantity on each axis, length :attr:`dim`."""
        return self._units

    # ------------------------------------------------------------------------------------ weight, gains, mask
    @property
    def weight(self) -> float:
        """Weight >= 0 in a weighted QP (dimensionless)."""
        return self._weight

    @weight.setter
    def weight(self, value: float) -> None:
        self._weight = val.as_weight(value, self.owner)
        Task._config_epoch += 1

    def _gain(self, value: Any, key: str) -> FloatArray:
        """Normalise a gain given as a scalar or one value per axis (subclasses may accept more forms)."""
        return val.as_gain(value, self._dim, self.owner, key)

    @property
    def kp(self) -> FloatArray:
        """Proportional gains, shape (dim,), read-only: 1/s^2 at acceleration level, 1/s at velocity level."""
        return self._kp

    @kp.setter
    def kp(self, value: Any) -> None:
        self._kp = self._gain(value, "kp")
        Task._config_epoch += 1

    @property
    def kd(self) -> FloatArray:
        """Derivative gains, shape (dim,), 1/s, read-only (acceleration level only)."""
        return self._kd

    @kd.setter
    def kd(self, value: Any) -> None:
        self._kd = self._gain(value, "kd")
        Task._config_epoch += 1

    @property
    def mask(self) -> npt.NDArray[np.bool_]:
        """Selected axes, (dim,) bool, read-only."""
        return self._mask

    @mask.setter
    def mask(self, value: Sequence[bool | int] | None) -> None:
        self._mask = val.as_mask(value, self._axis_names, self.owner)
        self._rows = val.frozen(np.flatnonzero(self._mask))
        self._all_selected = bool(self._mask.all())
        contiguous = self._rows[-1] - self._rows[0] + 1 == len(self._rows)
        self._selection: slice | npt.NDArray[np.intp] = (
            slice(int(self._rows[0]), int(self._rows[-1]) + 1) if contiguous else self._rows
        )
        Task._config_epoch += 1

    @property
    def rows(self) -> npt.NDArray[np.intp]:
        """Indices of the selected axes, increasing, read-only."""
        return self._rows

    @property
    def selection(self) -> slice | npt.NDArray[np.intp]:
        """The selected axes as an index usable on a (dim, ...) array: a slice when they are contiguous
        (cheaper, gives views), else :attr:`rows`."""
        return self._selection

    @property
    def all_selected(self) -> bool:
        """True when the mask selects every axis."""
        return self._all_selected

    # ---------------------------------------------------------------------------------------- references
    @property
    def v_ref(self) -> FloatArray:
        """Reference task velocity, shape (dim,), :attr:`units` per s, read-only."""
        return self._v_ref

    @property
    def a_ref(self) -> FloatArray:
        """Reference task acceleration (feed-forward), shape (dim,), :attr:`units` per s^2, read-only."""
        return self._a_ref

    def _check_derivatives(
        self, velocity: npt.ArrayLike | None, acceleration: npt.ArrayLike | None
    ) -> tuple[FloatArray, FloatArray]:
        """Validate a reference velocity and acceleration (``None`` means zero) without storing them."""
        if velocity is None or acceleration is None:
            zero = self._zero_reference()
        v = zero if velocity is None else val.frozen(val.as_vector(velocity, self._dim, self.owner, "velocity"))
        a = zero if acceleration is None else val.frozen(
            val.as_vector(acceleration, self._dim, self.owner, "acceleration"))
        return v, a

    def _zero_reference(self) -> FloatArray:
        """A read-only zero vector of the task's dimension, the same object every time (a reference left at zero
        is then recognised by identity, and nothing is allocated per tick)."""
        zero = getattr(self, "_zero_ref", None)
        if zero is None or zero.shape[0] != self._dim:
            zero = self._zero_ref = val.frozen(np.zeros(self._dim))
        return zero

    def _store_derivatives(self, derivatives: tuple[FloatArray, FloatArray]) -> None:
        """Store what :meth:`_check_derivatives` returned."""
        self._v_ref, self._a_ref = derivatives

    # ------------------------------------------------------------------------------- stacked evaluation
    # :class:`~wbcbench.tasks.TaskStack` fills preallocated buffers through these three hooks, once per tick.
    # Each writes the rows selected by the mask into ``out`` (a view of shape (r, nv) or (r,), r = len(rows)),
    # with the same values as ``jacobian(...)[selection]`` etc. The defaults go through the contract; the
    # library's tasks override them to skip temporaries and the rows their mask drops.

    def _write_jacobian(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        """``out[:] = jacobian(model, data)[selection]``."""
        J = self.jacobian(model, data)
        out[...] = J if self._all_selected else J[self._selection]

    def _write_error(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        """``out[:] = error(model, data)[selection]``."""
        e = self.error(model, data)
        out[...] = e if self._all_selected else e[self._selection]

    def _write_drift(self, model: pin.Model, data: pin.Data, out: FloatArray) -> None:
        """``out[:] = drift(model, data)[selection]``."""
        a = self.drift(model, data)
        out[...] = a if self._all_selected else a[self._selection]

    def _write_rows(self, model: pin.Model, data: pin.Data, J_out: FloatArray, e_out: FloatArray,
                    drift_out: FloatArray | None) -> None:
        """The three hooks above in one (``drift_out`` None: no drift, velocity level). A task whose rows share
        most of their work overrides this; the stack then calls it instead of the three."""
        self._write_jacobian(model, data, J_out)
        self._write_error(model, data, e_out)
        if drift_out is not None:
            self._write_drift(model, data, drift_out)

    def __repr__(self) -> str:
        selected = "".join("1" if m else "0" for m in self._mask)
        return f"{type(self).__name__}(name={self._name!r}, weight={self._weight:g}, mask={selected})"
