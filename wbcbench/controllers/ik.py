"""Hierarchical inverse kinematics at velocity level (paper 000 Section 3.1; Stack of Tasks).

The hierarchy (levels from the task set's `level:` keys, the feet first) is `KinematicHierarchy`
(ik_formulation.py), solved by lexicographic least squares (`wbcbench.qp.HierarchicalSolver`); TALOS: I CoM
height, II CoM x-y, III waist orientation, IV posture. The controller's policy: the solution is integrated once
on the manifold; the integrated configuration (not the measured one) feeds the next tick, and its joint
positions and velocities go to the joint servos. The task set's stabilizer (any `wbcbench.stabilizers` type;
TALOS: the DCM/CoM admittance) corrects the references in front of it.

A level that cannot be met (e.g. a target out of reach) is solved in the least-squares sense and counted
(`status()["unmet_level_ticks"]`; per-tick log `ik_unmet_level`: the highest-priority unmet level above the
last one, -1 for none); if the solver fails, the integrated posture is held with zero velocity.
"""

from __future__ import annotations

from pathlib import Path
from time import perf_counter

import numpy as np
import pinocchio as pin

from ..errors import ConfigError
from ..qp import HierarchicalSolver
from ..robots import Robot
from ..side import Side
from ..stabilizers.base import Stabilizer
from ..tasks import Contact6D, FrameTask
from ..tasks.registry import build_task
from ..types import ActuationMode, Command, Measurement, ModelFeedback, References
from .base import Controller
from .ik_formulation import KinematicHierarchy
from .plan_corrections import PlanCorrections
from .task_references import TaskReferences
from .taskset import TaskSetSpec, load_taskset, taskset_path

MAX_LEVELS = 8


class IKController(Controller):
    """Velocity-level hierarchical IK with positions sent to the joint servos; see the module docstring."""

    name = "ik"
    modes = (ActuationMode.POSITION, ActuationMode.SPD)
    default_mode = ActuationMode.POSITION

    def __init__(self, robot: Robot, mode: ActuationMode, dt: float, taskset: TaskSetSpec | str | Path | None = None,
                 stabilizer: Stabilizer | None = None):
        super().__init__(robot, mode, dt)
        if taskset is None or isinstance(taskset, (str, Path)):
            taskset = load_taskset(taskset or taskset_path(robot, self.name), robot, max_level=MAX_LEVELS)
        self.spec = spec = taskset
        m = self.model = robot.model
        hard = [t.name for t in spec.tasks if t.hard]
        if hard:
            raise ConfigError(f"task(s) {', '.join(hard)}: `hard` is for the inverse-dynamics QP; a hierarchy "
                              "orders tasks by `level`", file=spec.file, key="tasks")
        for key, given in (("drift", spec.contacts.drift != "spatial"),
                           ("wrench_metric", spec.contacts.wrench_metric is not None)):
            if given:
                raise ConfigError("is for the inverse-dynamics QP (contact accelerations and wrenches); the "
                                  "kinematic hierarchy has neither", file=spec.file, key=f"contacts.{key}")
        self.tasks = [build_task(robot, t) for t in spec.tasks]
        levels = [[task for task, ts in zip(self.tasks, spec.tasks) if ts.level == lv]
                  for lv in sorted({t.level for t in spec.tasks})]
        sole = robot.profile.sole
        c = spec.contacts
        contacts = {s: Contact6D(m, robot.profile.feet[s].frame, length=sole.length, width=sole.width, kp=c.kp,
                                 kd=0.0, name=f"contact_{s.value}", error=c.error) for s in Side}
        sw = spec.swing_foot
        swing = {s: FrameTask(m, robot.profile.feet[s].frame, name=f"swing_{s.value}", kp=sw.kp, kd=0.0,
                              mask=sw.mask) for s in Side}
        self.formulation = K = KinematicHierarchy(m, levels, contacts, swing, position_limits=robot.position_limits,
                                                  velocity_limit=robot.velocity_limit, dt=dt)
        self.data = K.data
        self.task_by_name = K.task_by_name
        self.level_names = K.level_names
        self.references = TaskReferences(self.tasks, swing, swing_pitch=spec.swing_pitch_with_leg)
        self.solver = HierarchicalSolver(m.nv, solver=spec.solver)
        # the task set's correction stages (plan lead, base feedback, stabilizer, ...: plan_corrections.py)
        self.corrections = PlanCorrections(robot, dt, spec, stabilizer)
        self._log_sources = self.corrections.log_sources
        self.n_unmet = 0
        self.n_failed = 0
        self.unmet_levels = -1
        self.v = np.zeros(m.nv)
        self._t_pin = self._t_solve = 0.0

    @property
    def stabilizer(self) -> Stabilizer | None:
        """The stabilizer in front of the solve (None: none), the task set's or the one given."""
        return self.corrections.stabilizer

    def reset(self, meas: Measurement, refs: References) -> None:
        K = self.formulation
        self.q_int = meas.q.copy()
        self.v = np.zeros(self.model.nv)
        K.update(self.q_int)
        K.reset_references(self.robot.q0, refs.contacts)
        self.corrections.reset(meas, refs, lambda: ModelFeedback(self.q_int, frozenset(refs.contacts)), self.q_int)
        self._warm_up()

    def _warm_up(self) -> None:
        """Solve this tick's hierarchy once, without acting: the compiled kernels are compiled (or loaded from
        their cache) here rather than in the first timed step. Nothing of the controller's state changes."""
        levels, lower, upper = self.formulation.problem()
        HierarchicalSolver(self.model.nv, solver=self.spec.solver).solve(levels, lower.copy(), upper.copy())

    def step(self, meas: Measurement, refs: References) -> Command:
        K = self.formulation
        refs = self.corrections.apply(meas, refs, self.q_int, self._stabilizer_feedback)
        t0 = perf_counter()
        K.update(self.q_int)
        self._t_pin = perf_counter() - t0
        self.references.apply(refs)
        K.set_contacts(refs.contacts)
        levels, lower, upper = K.problem()
        t0 = perf_counter()
        res = self.solve_qp(self.solver, levels, lower, upper)
        self._t_solve = perf_counter() - t0
        if not res.ok:
            self.n_failed += 1
            return Command(q=self.q_int[7:].copy(), v=np.zeros(self.robot.na))
        # the lowest level is a regularisation (posture) that lower-priority conflicts always leave unmet:
        # report the highest-priority level above it that could not be met (-1: none)
        met = res.met[:-1]
        if False in met:
            self.unmet_levels = met.index(False)
            self.n_unmet += 1
        else:
            self.unmet_levels = -1
        self.v = v = res.x
        self.q_int = q = pin.integrate(self.model, self.q_int, v * self.dt)
        return self.corrections.command(Command(None, q[7:].copy(), v[6:].copy()))

    def _stabilizer_feedback(self, refs: References) -> ModelFeedback:
        """What the stabilizer may know of the model: the integrated configuration and the planned contacts."""
        return ModelFeedback.of_tick(self.q_int, refs.contacts)

    @property
    def last_timing_us(self) -> dict[str, float]:
        return {"pinocchio": self._t_pin * 1e6, "solve": self._t_solve * 1e6}

    def log_channels(self) -> dict[str, list[str]]:
        ch = {"ik_unmet_level": []}
        ch.update(self.corrections.log_channels())  # the stabilizer's and any other logging stage's
        return ch

    def log_values(self) -> list:
        vals = [self.unmet_levels]
        for src in self._log_sources:
            vals.append(src.log)
        return vals

    def status(self) -> dict:
        return self.corrections.status({"unmet_level_ticks": self.n_unmet, "solver_failed_ticks": self.n_failed})
