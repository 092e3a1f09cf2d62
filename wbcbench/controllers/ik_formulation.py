"""The kinematic formulation: tasks grouped in strict-priority levels -> a velocity-level hierarchy.

Decision variable: the generalized velocity v (nv). Level 0 holds the contacts: a contact link in contact holds
its pose, a free one tracks its free-motion task (a swing foot); then the task levels in order. Every task row is
J v = v_ref + Kp e (velocity level, `wbcbench.tasks.velocity_rows`); tasks of one level are weighted against
each other. Hard bounds: the joint position limits reached in one step ((q_min - q) / dt <= v <= (q_max - q) / dt)
and the velocity limits. Per tick::

    K.update(q)                        # kinematics at the configuration the hierarchy is written at
    K.set_contacts(wanted)             # a contact made takes the frame's current pose as its reference
    levels, lower, upper = K.problem() # for wbcbench.qp.HierarchicalSolver

Solving and integrating are the controller's policy. The levels' arrays are reused tick after tick: valid until
the next `problem()`.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence

import numpy as np
import pinocchio as pin

from ..qp import EqualityTask, Level
from ..qp.levels import Task as LevelTask
from ..tasks import Task, TaskStack, update_kinematics_velocity_level
from . import _kernels

__all__ = ["KinematicHierarchy"]


class KinematicHierarchy:
    """Levels of tasks -> a strict hierarchy at velocity level (module docstring).

    Args:
        model: the robot's pinocchio model; the formulation keeps its own data.
        levels: the task levels in priority order (each a sequence of tasks weighted against each other).
        contacts: per contact name, the contact task (holds the link's pose while in contact).
        free_tasks: per contact name, the link's task while not in contact.
        position_limits: (q_lo, q_hi) (na,) [rad]; velocity_limit (na,) [rad/s] (replaceable attributes).
        dt: the control period [s].
    """

    #: frame, contact and CoM rows evaluated in one compiled call (`TaskStack(compiled_frames=...)`): pinocchio's
    #: rows to rounding (tests/tasks/test_compiled_rows.py compares the commands)
    compiled_frames = True

    def __init__(self, model: pin.Model, levels: Sequence[Sequence[Task]], contacts: Mapping, free_tasks: Mapping,
                 *, position_limits: tuple[np.ndarray, np.ndarray], velocity_limit: np.ndarray, dt: float):
        self.model = model
        self.data = model.createData()
        self.nv = model.nv
        self.levels = [list(lv) for lv in levels]
        self.level_names = ["feet"] + ["+".join(t.name for t in lv) for lv in self.levels]
        self.tasks = [t for lv in self.levels for t in lv]
        self.task_by_name = {t.name: t for t in self.tasks}
        self.contacts = dict(contacts)
        self.free_tasks = dict(free_tasks)
        self.names = tuple(self.contacts)
        self.in_contact = {n: True for n in self.names}
        self._key: tuple[bool, ...] = tuple(True for _ in self.names)  # in_contact's values in `names` order
        self._wanted: frozenset | None = None  # the contact set of the last `set_contacts` (a frozenset)
        self.q_lo, self.q_hi = position_limits
        self.v_max = velocity_limit
        self.dt = dt
        self.lower = np.full(self.nv, -np.inf)
        self.upper = np.full(self.nv, np.inf)
        self._q = None
        # per contact state: the stack of every task's rows and the levels handed to the solver, whose tasks are
        # views of the stack's rows (see `problem`)
        self._plans: dict[tuple[bool, ...], list] = {}
        self._limits: tuple = (None, None, None, None)

    def update(self, q: np.ndarray) -> None:
        update_kinematics_velocity_level(self.model, self.data, q)
        self._q = q

    def reset_references(self, q_reference: np.ndarray, active: Collection) -> None:
        """At rest (after `update`): every task's reference to its rest value, the contacts' and free tasks'
        references to where their frames are, the contacts in `active` in contact."""
        m, d = self.model, self.data
        for t in self.tasks:
            t.reset_reference(m, d, q_reference)
        for n in self.names:
            self.contacts[n].set_reference_to_current(m, d)
            self.free_tasks[n].set_reference_to_current(m, d)
            self.in_contact[n] = n in active
        self._key = tuple(self.in_contact[n] for n in self.names)
        self._wanted = None

    def set_contacts(self, wanted: Collection) -> None:
        """A contact made this tick takes its frame's current pose as its reference (the model's touch-down)."""
        if wanted is self._wanted:  # the plan's contact set of the last tick (a phase keeps its frozenset)
            return
        self._wanted = wanted if type(wanted) is frozenset else None
        in_contact = self.in_contact
        changed = False
        for n in self.names:
            want = n in wanted
            if want != in_contact[n]:
                if want:
                    self.contacts[n].set_reference_to_current(self.model, self.data)
                in_contact[n] = want
                changed = True
        if changed:
            self._key = tuple(in_contact[n] for n in self.names)

    def bounds(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Velocity bounds at configuration q: joint position limits reached in one step and velocity limits."""
        limits = self._limits
        if limits[0] is not self.q_lo or limits[1] is not self.q_hi or limits[2] is not self.v_max:
            limits = self._limits = (self.q_lo, self.q_hi, self.v_max, np.stack([self.q_lo, self.q_hi]))
        _kernels.ik_bounds(limits[3], self.v_max, q[7:], self.dt, self.lower, self.upper)
        return self.lower, self.upper

    def problem(self) -> tuple[tuple[Level, ...], np.ndarray, np.ndarray]:
        """The levels of this tick (contacts, then the task levels), their rows evaluated, and the bounds.

        The rows of every task come from one :class:`~wbcbench.tasks.TaskStack` (per contact state), evaluated
        in place; the levels are built once per stack layout with light containers whose arrays are views of the
        stack's rows: the solver gets the same levels object every tick, with this tick's rows."""
        key = self._key
        plan = self._plans.get(key)
        if plan is None:
            feet = [self.contacts[n] if c else self.free_tasks[n] for n, c in zip(self.names, key, strict=True)]
            plan = self._plans[key] = [TaskStack(feet + self.tasks, self.nv, compiled_frames=self.compiled_frames),
                                       None, None, len(feet)]
        stack = plan[0]
        A, b = stack.velocity_rows(self.model, self.data)
        slices = stack.slices
        if plan[1] is not slices:  # new layout (first tick, or a gain, weight or mask changed): new views
            items = iter(zip(stack.tasks, slices, strict=True))
            feet: list[LevelTask] = [EqualityTask._trusted(t.name, A[sl], b[sl]) for t, sl in
                                     (next(items) for _ in range(plan[3]))]
            levels = [Level._trusted(tuple(feet), "feet")]
            for lv, name in zip(self.levels, self.level_names[1:], strict=True):
                tasks: list[LevelTask] = []
                for _ in lv:
                    t, sl = next(items)
                    tasks.append(EqualityTask._trusted(t.name, A[sl], b[sl], t.weight))
                levels.append(Level._trusted(tuple(tasks), name))
            plan[1], plan[2] = slices, tuple(levels)
        lower, upper = self.bounds(self._q)
        return plan[2], lower, upper
