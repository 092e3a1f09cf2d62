"""Several tasks' rows evaluated together, into buffers allocated once, every control tick.

:func:`~wbcbench.tasks.acceleration_rows` and :func:`~wbcbench.tasks.velocity_rows` build one task's rows
from its contract (error, Jacobian, velocity, drift), allocating a few arrays each. A controller that needs
the rows of all its tasks every tick pays that, plus the Python around it, once per task. A
:class:`TaskStack` keeps the stacked arrays and the stacked gains of a list of tasks and fills them in
place: each task writes its selected Jacobian rows, error and drift into its slice of the buffers
(``Task._write_jacobian`` / ``_write_error`` / ``_write_drift``), then the control law is applied to all rows
at once, with the task velocities ``J v`` as one product of the stacked Jacobian with ``v`` (the task
contract: ``velocity()`` is ``J v``).

Same rows as stacking the per-task functions, to rounding (the velocity as ``J v`` rather than pinocchio's
frame velocity differs by a few 1e-16 relative), in the order of the tasks given.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from wbcbench.jit import njit
from wbcbench.tasks.com_task import CoMTask
from wbcbench.tasks.contact_6d import Contact6D
from wbcbench.tasks.frame_batch import FrameBatch
from wbcbench.tasks.frame_task import FrameTask
from wbcbench.tasks.rows import Rows
from wbcbench.tasks.task import Task

__all__ = ["TaskStack"]

FloatArray = npt.NDArray[np.float64]


_IN_BATCH = "frame batch"  # a stack item whose rows the FrameBatch writes


def _read_only(array: FloatArray) -> FloatArray:
    view = array.view()
    view.flags.writeable = False
    return view


class TaskStack:
    """The rows of several tasks, stacked: ``A`` (m, nv) and ``b`` (m,).

    Acceleration level (:meth:`acceleration_rows`, after :func:`~wbcbench.tasks.update_kinematics`)::

        A = [J_1[mask_1]; J_2[mask_2]; ...]
        b = a_ref + Kd (v_ref - A v) + Kp e - J_dot v          (every row at once)

    Velocity level (:meth:`velocity_rows`, after either kinematics update)::

        b = v_ref + Kp e

    The layout (row offsets, stacked gains and square-root weights, the constant Jacobian rows of posture
    tasks) is built at the first evaluation and rebuilt whenever a weight, gain or mask of any task changes
    (one integer comparison per evaluation, see ``Task._config_epoch``; when it changed, the stack's own tasks
    are compared with the layout's, so new tasks elsewhere cost no rebuild). References are read from the tasks at
    every evaluation (copied only when a ``set_reference`` replaced them).

    Args:
        tasks: the tasks, in row order.
        nv: number of columns (the model's ``nv``).
        skip_zero_weight: leave out the tasks whose weight is 0 (nothing they give counts in a weighted cost);
            re-evaluated when a weight changes. True for every task, or the collection of tasks it applies to
            (e.g. the cost tasks of a stack that also holds constraints).
        compiled_frames: fill the rows of the frame tasks, contacts and CoM tasks
            (:class:`~wbcbench.tasks.FrameTask`, :class:`~wbcbench.tasks.Contact6D`, :class:`~wbcbench.tasks.CoMTask`,
            not subclasses) with one compiled call (:mod:`wbcbench.tasks.frame_batch`): the same rows to rounding,
            not the same bits, faster by a few us per task. Models the compiled kinematics does not support keep
            the tasks' own evaluation.

    The arrays returned are read-only views of the stack's buffers, overwritten by the next evaluation (copy
    them to keep them). Not thread-safe.
    """

    def __init__(self, tasks: Sequence[Task], nv: int, *, skip_zero_weight: bool | Collection[Task] = False,
                 compiled_frames: bool = False) -> None:
        self._candidates = tuple(tasks)
        self._compiled_frames = bool(compiled_frames)
        self._nv = int(nv)
        if isinstance(skip_zero_weight, bool):
            self._skippable = frozenset(map(id, self._candidates)) if skip_zero_weight else frozenset()
        else:
            self._skippable = frozenset(map(id, skip_zero_weight))
        self._epoch: int | None = None
        self._pending_constant = False
        self._layout_now()

    # ------------------------------------------------------------------------------------------ layout
    def _layout_now(self) -> None:
        tasks = [t for t in self._candidates if not (t.weight == 0.0 and id(t) in self._skippable)]
        sizes = [len(t.rows) for t in tasks]
        m, nv = sum(sizes), self._nv
        self._A = np.zeros((m, nv))
        self._b = np.zeros(m)
        self._e = np.zeros(m)
        self._drift = np.zeros(m)
        self._v_ref = np.zeros(m)
        self._a_ref = np.zeros(m)
        self._jv = np.zeros(m)
        kp, kd, sw = np.empty(m), np.empty(m), np.empty(m)
        items: list[tuple] = []
        slices: list[slice] = []
        batched: list[tuple[Task, int]] = []
        start = 0
        for task, r in zip(tasks, sizes, strict=True):
            rows = slice(start, start + r)
            sel = task.selection
            kp[rows] = task.kp[sel]
            kd[rows] = task.kd[sel]
            sw[rows] = math.sqrt(task.weight)
            # (task, its hooks and row views; [last v_ref, last a_ref] seen); no Jacobian hook when constant
            # how the rows are written: the frame batch, the task's own combined hook, or its three hooks (None)
            if self._compiled_frames and type(task) in (FrameTask, Contact6D, CoMTask):
                how = _IN_BATCH
                batched.append((task, start))
            elif type(task)._write_rows is not Task._write_rows and not task._constant_jacobian:
                how = task._write_rows
            else:
                how = None
            items.append((task, None if task._constant_jacobian else task._write_jacobian, self._A[rows],
                          task._write_error, self._e[rows], task._write_drift, self._drift[rows],
                          self._v_ref[rows], self._a_ref[rows], [None, None], how))
            slices.append(rows)
            start += r
        self._kp, self._kd, self._minus_kd = kp, kd, -kd
        self._v_ref_zero = self._a_ref_zero = True  # the reference rows are zeros until filled
        self._sqrt_weights = _read_only(sw)
        self._items = items
        self._split_items()
        self._batched = batched
        self._batch = None  # FrameBatch, built at the first evaluation (it needs the model)
        self._tasks = tuple(tasks)
        self._slices = tuple(slices)
        self._A_out, self._b_out = _read_only(self._A), _read_only(self._b)
        self._rows_out = Rows(self._A_out, self._b_out)  # the same views every evaluation
        self._pending_constant = any(t._constant_jacobian for t in tasks)
        self._layout_signature = self._signature()
        self._epoch = Task._config_epoch

    def _split_items(self) -> None:
        """From `_items`: the hooks to call per tick (the tasks not in the frame batch) and, for every task, where
        its references go (two loops with nothing to test per item, instead of one over everything)."""
        self._hooks = [(how, write_jacobian, J, write_error, e, write_drift, a)
                       for _, write_jacobian, J, write_error, e, write_drift, a, _, _, _, how in self._items
                       if how is not _IN_BATCH]
        self._ref_rows = [(task, v_ref_rows, a_ref_rows, seen)
                          for task, _, _, _, _, _, _, v_ref_rows, a_ref_rows, seen, _ in self._items]

    def _signature(self) -> tuple:
        """What the layout depends on: each task's weight, gains and rows (setters store new arrays)."""
        return tuple((t._weight, t._kp, t._kd, t._rows) for t in self._candidates)

    def _update_layout(self) -> None:
        """Some task's configuration changed (any task's, anywhere): rebuild the layout if one of ours did."""
        signature = self._signature()
        if len(signature) != len(self._layout_signature) or any(
            a[0] != b[0] or a[1] is not b[1] or a[2] is not b[2] or a[3] is not b[3]
            for a, b in zip(signature, self._layout_signature)
        ):
            self._layout_now()
        else:
            self._epoch = Task._config_epoch

    def _refresh(self, model: pin.Model, data: pin.Data) -> None:
        """Rebuild the layout if a task's configuration changed; write the constant Jacobian rows."""
        if self._epoch != Task._config_epoch:
            self._update_layout()
        if self._pending_constant:
            for task, rows in zip(self._tasks, self._slices, strict=True):
                if task._constant_jacobian:
                    task._write_jacobian(model, data, self._A[rows])
            self._pending_constant = False

    # ---------------------------------------------------------------------------------------- evaluation
    def _fill(self, model: pin.Model, data: pin.Data, drift: bool) -> None:
        batch = self._batch
        if batch is None and self._batched:
            batch = self._batch = FrameBatch(model, *zip(*self._batched))
            if not batch.supported:  # the model's joints: the tasks' own hooks
                self._items = [item[:-1] + (None if item[-1] is _IN_BATCH else item[-1],) for item in self._items]
                self._split_items()
        if batch is not None and batch.supported:
            batch.fill(model, data, self._A, self._e, self._drift if drift else None)
        for how, write_jacobian, J, write_error, e, write_drift, a in self._hooks:
            if how is None:
                if write_jacobian is not None:
                    write_jacobian(model, data, J)
                write_error(model, data, e)
                if drift:
                    write_drift(model, data, a)
            else:
                how(model, data, J, e, a if drift else None)
        v_changed = a_changed = False
        for task, v_ref_rows, a_ref_rows, seen in self._ref_rows:
            v_ref = task._v_ref
            if v_ref is not seen[0]:  # set_reference stores new (read-only) arrays: copy only when replaced
                v_ref_rows[...] = v_ref if task._all_selected else v_ref[task._selection]
                seen[0] = v_ref
                v_changed = True
            if drift:
                a_ref = task._a_ref
                if a_ref is not seen[1]:
                    a_ref_rows[...] = a_ref if task._all_selected else a_ref[task._selection]
                    seen[1] = a_ref
                    a_changed = True
        # (NaN counts, as in `any`; a third of its time); the velocity level never reads the accelerations, whose
        # test waits for the first evaluation that copies them
        if v_changed:
            self._v_ref_zero = not np.count_nonzero(self._v_ref)
        if a_changed:
            self._a_ref_zero = not np.count_nonzero(self._a_ref)

    def acceleration_rows(self, model: pin.Model, data: pin.Data) -> Rows:
        """Stacked ``J dv = a_ref + Kd (v_ref - J v) + Kp e - J_dot v`` (see
        :func:`~wbcbench.tasks.acceleration_rows`); needs :func:`~wbcbench.tasks.update_kinematics` for the
        current ``(q, v)`` (``v`` is read from ``data.v_in``).

        Returns:
            ``Rows(A (m, nv), b (m,))``, read-only views valid until the next evaluation.
        """
        if self._epoch != Task._config_epoch or self._pending_constant:
            self._refresh(model, data)
        self._fill(model, data, True)
        np.matmul(self._A, data.v_in, out=self._jv)
        _acceleration_law(self._jv, self._kp, self._minus_kd, self._e, self._v_ref, self._a_ref, self._drift,
                          not self._v_ref_zero, not self._a_ref_zero, self._b)
        return self._rows_out

    def velocity_rows(self, model: pin.Model, data: pin.Data) -> Rows:
        """Stacked ``J v = v_ref + Kp e`` (see :func:`~wbcbench.tasks.velocity_rows`); needs either kinematics
        update for the current ``q``.

        Returns:
            ``Rows(A (m, nv), b (m,))``, read-only views valid until the next evaluation.
        """
        if self._epoch != Task._config_epoch or self._pending_constant:
            self._refresh(model, data)
        self._fill(model, data, False)
        _velocity_law(self._kp, self._e, self._v_ref, not self._v_ref_zero, self._b)
        return self._rows_out

    # ---------------------------------------------------------------------------------------- description
    @property
    def tasks(self) -> tuple[Task, ...]:
        """The tasks in the current layout (without the zero-weight ones when they are skipped), in row order."""
        if self._epoch != Task._config_epoch:
            self._update_layout()
        return self._tasks

    @property
    def slices(self) -> tuple[slice, ...]:
        """Rows of each task of :attr:`tasks` in ``A`` and ``b``."""
        if self._epoch != Task._config_epoch:
            self._update_layout()
        return self._slices

    @property
    def sqrt_weights(self) -> FloatArray:
        """``sqrt(weight)`` of each row's task, (m,), read-only."""
        if self._epoch != Task._config_epoch:
            self._update_layout()
        return self._sqrt_weights

    @property
    def n_rows(self) -> int:
        """Number of stacked rows ``m``."""
        return self.sqrt_weights.shape[0]


@njit(exact=True)
def _acceleration_law(jv, kp, minus_kd, e, v_ref, a_ref, drift, with_v_ref, with_a_ref, b):
    """``b = a_ref + Kd (v_ref - jv) + Kp e - drift`` row by row (``jv = J v``, numpy's product), the numpy
    expression it replaces operation by operation (no reassociation, no fused multiply-add: the same numbers); the
    terms of zero references skipped (the same numbers: 0 - Jv = -Jv, 0 + x = x)."""
    for r in range(b.shape[0]):
        s = jv[r]
        if with_v_ref:
            x = (v_ref[r] - s) * -minus_kd[r]
        else:
            x = s * minus_kd[r]
        if with_a_ref:
            x = a_ref[r] + x
        b[r] = x + kp[r] * e[r] - drift[r]


@njit(exact=True)
def _velocity_law(kp, e, v_ref, with_v_ref, b):
    """``b = Kp e + v_ref`` row by row: numpy's ``multiply`` then ``add`` it replaces (the same numbers), the
    reference's term skipped when it is zero (``x + 0 = x``)."""
    for r in range(b.shape[0]):
        x = kp[r] * e[r]
        if with_v_ref:
            x = v_ref[r] + x
        b[r] = x
