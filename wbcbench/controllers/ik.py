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

from ..qp import EqualityTask, HierarchicalSolver, Level
from ..robots import Robot
from ..side import Side
from ..sim.model import ActuationMode
from ..stabilizers.balance import BalanceStabilizer
from ..tasks import Contact6D, FrameTask, update_kinematics_velocity_level, velocity_rows
from ..types import Command, Measurement, References
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
        self.q_lo, self.q_hi = robot.position_limits
        self.v_max = robot.velocity_limit
        self.lower = np.full(m.nv, -np.inf)
        self.upper = np.full(m.nv, np.inf)
        self.stabilizer = BalanceStabilizer(robot, self.spec.stabilizer, dt) if self.spec.stabilizer else None
        self.in_contact = {s: True for s in Side}
        self.n_unmet = 0
        self.n_failed = 0
        self.unmet_levels = -1
        self.v = np.zeros(m.nv)
        self._t_pin = self._t_solve = 0.0

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

    def step(self, meas: Measurement, refs: References) -> Command:
        m, d = self.model, self.data
        if self.stabilizer is not None:
            refs = self.stabilizer.correct(meas, refs, self.q_int)
        t0 = perf_counter()
        update_kinematics_velocity_level(m, d, self.q_int)
        self._t_pin = perf_counter() - t0
        # references
        if refs.com is not None:
            for t in self.com_tasks:
                t.set_reference(refs.com, refs.com_vel if refs.com_vel is not None else np.zeros(3))
        for s in Side:
            wanted = s in refs.contacts
            if wanted and not self.in_contact[s]:
                self.contacts[s].set_reference_to_current(m, d)  # touch-down where the model's foot is
            self.in_contact[s] = wanted
        for name, target in refs.targets.items():
            task = self.task_by_name.get(name)
            if task is not None:
                task.set_reference(*(target[:2] if isinstance(target, tuple) else (target,)))
        for s, (p, vel, _acc) in refs.feet.items():
            R = refs.feet_rotation.get(s, self.swing[s].reference.rotation)
            self.swing[s].set_reference(pin.SE3(R, np.asarray(p)), np.concatenate([vel, np.zeros(3)]))
        # levels
        feet = []
        for s in Side:
            task = self.contacts[s] if self.in_contact[s] else self.swing[s]
            A, b = velocity_rows(task, m, d)
            feet.append(EqualityTask(task.name, A, b))
        levels = [Level(tuple(feet), "feet")]
        for lv, name in zip(self.levels, self.level_names[1:]):
            tasks = []
            for task in lv:
                A, b = velocity_rows(task, m, d)
                tasks.append(EqualityTask(task.name, A, b, task.weight))
            levels.append(Level(tuple(tasks), name))
        # bounds: joint position limits as velocities, velocity limits
        qj = self.q_int[7:]
        self.lower[6:] = np.maximum((self.q_lo - qj) / self.dt, -self.v_max)
        self.upper[6:] = np.minimum((self.q_hi - qj) / self.dt, self.v_max)
        np.minimum(self.lower, self.upper, out=self.lower)
        t0 = perf_counter()
        res = self.solver.solve(levels, self.lower, self.upper)
        self._t_solve = perf_counter() - t0
        if not res.ok:
            self.n_failed += 1
            return Command(q=self.q_int[7:].copy(), v=np.zeros(self.robot.na))
        # the lowest level is a regularisation (posture) that lower-priority conflicts always leave unmet:
        # report the highest-priority level above it that could not be met (-1: none)
        unmet = [r.index for r in res.levels[:-1] if not r.met]
        self.unmet_levels = unmet[0] if unmet else -1
        if unmet:
            self.n_unmet += 1
        self.v = res.x
        self.q_int = pin.integrate(m, self.q_int, self.v * self.dt)
        return Command(q=self.q_int[7:].copy(), v=self.v[6:].copy())

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
