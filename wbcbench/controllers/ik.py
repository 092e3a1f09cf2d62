"""Hierarchical inverse kinematics at velocity level (paper 000 Section 3.1; Stack of Tasks).

Decision variable: the generalized velocity v (nv). Levels in strict priority (lexicographic least squares,
`wbcbench.qp.HierarchicalSolver`): 0 the feet (a foot in contact holds its pose, a swinging foot tracks its
trajectory), then the task set's levels (TALOS: I CoM height, II CoM x-y, III waist orientation, IV posture).
Every task row is J v = v_ref + Kp e. Hard bounds: joint position limits turned into velocity bounds
((q_min - q) / dt <= v <= (q_max - q) / dt) and the URDF velocity limits. The solution is integrated once
on the manifold; the integrated configuration (not the measured one) feeds the next tick, and its joint
positions and velocities go to the joint servos. A DCM/CoM-admittance stabilizer corrects the CoM reference
in front of it when the task set configures one.

A level that cannot be met (e.g. a target out of reach) is solved in the least-squares sense and counted
(`status()["unmet_level_ticks"]`; per-tick log `ik_unmet_level`: the highest-priority unmet level above the
last one, -1 for none); if the solver fails, the integrated posture is held with zero velocity.
"""

from __future__ import annotations

from time import perf_counter

import numpy as np
import pinocchio as pin

from ..qp import EqualityTask, HierarchicalSolver, Level, _jit
from ..qp.levels import Task as LevelTask
from ..robots import Robot
from ..side import Side
from ..sim.model import ActuationMode
from ..estimation.base_feedback import BaseFeedback
from ..stabilizers.balance import BalanceStabilizer
from ..tasks import Contact6D, FrameTask, TaskStack, update_kinematics_velocity_level
from ..types import Command, Measurement, References
from . import _kernels
from .base import Controller, register
from .inverse_dynamics import build_task
from .taskset import TaskSetSpec, load_taskset, taskset_path

MAX_LEVELS = 8


@register
class IKController(Controller):
    """Velocity-level hierarchical IK with positions sent to the joint servos; see the module docstring."""

    name = "ik"
    modes = (ActuationMode.POSITION, ActuationMode.SPD)
    default_mode = ActuationMode.POSITION

    def __init__(self, robot: Robot, mode: ActuationMode, dt: float, taskset: TaskSetSpec | None = None):
        super().__init__(robot, mode, dt)
        self.spec = taskset or load_taskset(taskset_path(robot, self.name), robot, max_priority=MAX_LEVELS)
        m = self.model = robot.model
        self.data = m.createData()
        self.tasks = [build_task(robot, t) for t in self.spec.tasks]
        self.task_by_name = {t.name: t for t in self.tasks}
        priorities = sorted({t.priority for t in self.spec.tasks})
        if 0 in priorities:
            from ..errors import ConfigError
            raise ConfigError("priority 0 is the feet level; give tasks priorities >= 1", file=self.spec.file,
                              key="tasks")
        self.levels = [[task for task, spec in zip(self.tasks, self.spec.tasks) if spec.priority == p]
                       for p in priorities]
        self.level_names = ["feet"] + ["+".join(t.name for t in lv) for lv in self.levels]
        sole = robot.profile.sole
        c = self.spec.contacts
        self.contacts = {s: Contact6D(m, robot.profile.feet[s].frame, length=sole.length, width=sole.width,
                                      kp=c.kp, kd=0.0, name=f"contact_{s.value}") for s in Side}
        sw = self.spec.swing_foot
        self.swing = {s: FrameTask(m, robot.profile.feet[s].frame, name=f"swing_{s.value}", kp=sw.kp, kd=0.0,
                                   mask=sw.mask) for s in Side}
        self.solver = HierarchicalSolver(m.nv, solver=self.spec.solver)
        self.jit = _jit.JIT_ENABLED  # compiled bounds (controllers/_kernels.py); False: the numpy reference
        self.q_lo, self.q_hi = robot.position_limits
        self.v_max = robot.velocity_limit
        self.lower = np.full(m.nv, -np.inf)
        self.upper = np.full(m.nv, np.inf)
        self.stabilizer = BalanceStabilizer(robot, self.spec.stabilizer, dt) if self.spec.stabilizer else None
        self.base_feedback = BaseFeedback(robot, dt, self.spec.base_feedback) if self.spec.base_feedback else None
        self.in_contact = {s: True for s in Side}
        self.n_unmet = 0
        self.n_failed = 0
        self.unmet_levels = -1
        self.v = np.zeros(m.nv)
        self._t_pin = self._t_solve = 0.0
        self._sides = tuple(Side)
        # per contact state (left, right in contact): the stack of every task's rows and the levels handed to the
        # solver, whose tasks are views of the stack's rows (see _levels_for)
        self._plans: dict[tuple[bool, ...], list] = {}
        self._limits: tuple = (None, None, None)

    def reset(self, meas: Measurement, refs: References) -> None:
        m, d = self.model, self.data
        self.q_int = meas.q.copy()
        self.v = np.zeros(m.nv)
        update_kinematics_velocity_level(m, d, self.q_int)
        for t in self.tasks:
            if t.name == "posture" or type(t).__name__ == "PostureTask":
                t.set_reference(self.robot.q0)
            elif type(t).__name__ == "AngularMomentumTask":
                t.set_reference()
            else:
                t.set_reference_to_current(m, d)
        self.com_tasks = [t for t in self.tasks if type(t).__name__ == "CoMTask"]
        for s in Side:
            self.contacts[s].set_reference_to_current(m, d)
            self.swing[s].set_reference_to_current(m, d)
            self.in_contact[s] = s in refs.contacts
        if self.stabilizer is not None:
            self.stabilizer.reset(self.q_int)
        if self.jit:
            self._warm_up()

    def _warm_up(self) -> None:
        """Solve this tick's hierarchy once, without acting: the compiled kernels are compiled (or loaded from
        their cache) here rather than in the first timed step. Nothing of the controller's state changes."""
        levels = self._levels_for(tuple(self.in_contact[s] for s in self._sides))
        lower, upper = np.full(self.model.nv, -np.inf), np.full(self.model.nv, np.inf)
        _kernels.ik_bounds(np.stack([self.q_lo, self.q_hi]), self.v_max, self.q_int[7:], self.dt, lower, upper)
        HierarchicalSolver(self.model.nv, solver=self.spec.solver).solve(levels, lower, upper)

    def step(self, meas: Measurement, refs: References) -> Command:
        m, d = self.model, self.data
        if self.base_feedback is not None:
            refs = self.base_feedback.correct(meas, refs, self.q_int)
        if self.stabilizer is not None:
            refs = self.stabilizer.correct(meas, refs, self.q_int)
        t0 = perf_counter()
        update_kinematics_velocity_level(m, d, self.q_int)
        self._t_pin = perf_counter() - t0
        # references
        if refs.com is not None:
            for t in self.com_tasks:
                t.set_reference(refs.com, refs.com_vel if refs.com_vel is not None else np.zeros(3))
        contacts = refs.contacts
        key = []
        for s in self._sides:
            wanted = s in contacts
            if wanted and not self.in_contact[s]:
                self.contacts[s].set_reference_to_current(m, d)  # touch-down where the model's foot is
            self.in_contact[s] = wanted
            key.append(wanted)
        for name, target in refs.targets.items():
            task = self.task_by_name.get(name)
            if task is not None:
                task.set_reference(*(target[:2] if isinstance(target, tuple) else (target,)))
        for s, (p, vel, _acc) in refs.feet.items():
            R = refs.feet_rotation.get(s)
            if R is None:
                R = self.swing[s].reference.rotation
            self.swing[s].set_reference(pin.SE3(R, np.asarray(p)), np.concatenate([vel, np.zeros(3)]))
        # levels: every task's rows, refreshed in place
        levels = self._levels_for(tuple(key))
        # bounds: joint position limits as velocities, velocity limits
        # (both rows at once: [q_lo; q_hi] stacked, rebuilt when a limit attribute is replaced)
        limits = self._limits
        if limits[0] is not self.q_lo or limits[1] is not self.q_hi or limits[2] is not self.v_max:
            limits = self._limits = (self.q_lo, self.q_hi, self.v_max, np.stack([self.q_lo, self.q_hi]),
                                     -self.v_max, np.empty((2, self.robot.na)))
        if self.jit:
            _kernels.ik_bounds(limits[3], self.v_max, self.q_int[7:], self.dt, self.lower, self.upper)
        else:
            T = limits[5]
            np.subtract(limits[3], self.q_int[7:], out=T)
            T /= self.dt
            np.maximum(T[0], limits[4], out=self.lower[6:])
            np.minimum(T[1], self.v_max, out=self.upper[6:])
            np.minimum(self.lower, self.upper, out=self.lower)
        t0 = perf_counter()
        res = self.solver.solve(levels, self.lower, self.upper)
        self._t_solve = perf_counter() - t0
        if not res.ok:
            self.n_failed += 1
            return Command(q=self.q_int[7:].copy(), v=np.zeros(self.robot.na))
        # the lowest level is a regularisation (posture) that lower-priority conflicts always leave unmet:
        # report the highest-priority level above it that could not be met (-1: none)
        unmet = [k for k, met in enumerate(res.met[:-1]) if not met]
        self.unmet_levels = unmet[0] if unmet else -1
        if unmet:
            self.n_unmet += 1
        self.v = res.x
        self.q_int = pin.integrate(m, self.q_int, self.v * self.dt)
        return Command(q=self.q_int[7:].copy(), v=self.v[6:].copy())

    def _levels_for(self, in_contact: tuple[bool, ...]) -> tuple[Level, ...]:
        """The levels of this tick (feet, then the task set's levels), their rows evaluated.

        The rows of every task come from one :class:`~wbcbench.tasks.TaskStack` (per contact state), evaluated
        in place each tick; the levels are built once per stack layout with light containers whose arrays are
        views of the stack's rows: the solver gets the same levels object every tick, with this tick's rows
        (so the levels of a tick are valid until the next step)."""
        plan = self._plans.get(in_contact)
        if plan is None:
            feet = [self.contacts[s] if c else self.swing[s] for s, c in zip(self._sides, in_contact, strict=True)]
            tasks = feet + [t for lv in self.levels for t in lv]
            plan = self._plans[in_contact] = [TaskStack(tasks, self.model.nv), None, None, len(feet)]
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
        return plan[2]

    @property
    def last_timing_us(self) -> dict[str, float]:
        return {"pinocchio": self._t_pin * 1e6, "solve": self._t_solve * 1e6}

    def log_channels(self) -> dict[str, list[str]]:
        return {"ik_unmet_level": [], "stabilizer": BalanceStabilizer.LOG_LABELS}

    def log_values(self) -> list:
        stab = self.stabilizer.log if self.stabilizer is not None else np.full(6, np.nan)
        return [self.unmet_levels, stab]

    def status(self) -> dict:
        return {"unmet_level_ticks": self.n_unmet, "solver_failed_ticks": self.n_failed}
