"""`tsid-teleop`: the TSID-like weighted QP with the teleoperation task set (paper 004 Table I), the
self-collision repulsors (Eq. 8-13) and the force-based stabilizer (Eq. 2-7) in front.

It is `InverseDynamicsController` (inverse_dynamics.py) with three additions, made by subclassing and composition
so that the QP's internals stay untouched:

* the task set is `tasksets/<robot>/teleop.yaml` (Table I); `repulsors=False` drops its `self_collision`
  tasks (the paper's Table II condition);
* `TeleopStabilizer` (wbcbench/stabilizers/teleop.py) corrects the references each tick from the ankle F/T
  sensors: the CoM reference (Eq. 2), the contact (ankle) orientations (Eq. 3), the torso roll (Eq. 4-5), and
  wrench targets from the ZMP distributor (Eq. 6-7);
* wrench targets: the QP regularises each contact wrench towards zero (`regularization.wrench`); the paper's
  contact force regularisation task pulls it towards a target instead: F* of Eq. 7 when the ZMP distributor
  runs, else F, the split of the reference ZMP between the feet (Eq. 6 on the CoM reference's cart-table ZMP,
  `reference_wrench_targets`). The solvers are wrapped (`_WrenchTargetSolver`) so that each QP gets
  `w_f ||w_i - w_i*||^2` added on the wrench variables of the active contacts (a copy of H and g; the layout
  x = [dv; w_1; ...] of inverse_dynamics.py). In position and SPD modes the split between the feet is not
  determined by the motion: without a target it drifts from tick to tick, and the foot force difference
  (Eq. 4-5) and CoM admittance (Eq. 2), which compare it with the measured forces, wind up.

Default mode: SPD (stable PD at the joints, as the paper in simulation); position and torque also work.
"""

from __future__ import annotations

from dataclasses import replace
from time import perf_counter

import numpy as np
import pinocchio as pin

from ..qp.problem import QPProblem
from ..robots import Robot, Side
from ..sim.model import ActuationMode
from ..types import Command, Measurement, References
from .base import register
from .inverse_dynamics import QP_OK, InverseDynamicsController
from .taskset import TaskSetSpec, load_taskset, taskset_path

__all__ = ["TSIDTeleop", "teleop_taskset"]

TASKSET_NAME = "teleop"


def teleop_taskset(robot: Robot, *, repulsors: bool = True) -> TaskSetSpec:
    """The robot's teleoperation task set (tasksets/<robot>/teleop.yaml), without its self-collision tasks when
    `repulsors` is False."""
    spec = load_taskset(taskset_path(robot, TASKSET_NAME), robot)
    if not repulsors:
        spec = replace(spec, tasks=tuple(t for t in spec.tasks if t.type != "self_collision"))
    return spec


class _WrenchTargetSolver:
    """Wraps a QP solver: adds `weight ||w_i - w_i*||^2` for the active contacts' wrench variables."""

    def __init__(self, solver, controller: "TSIDTeleop"):
        self.solver = solver
        self.controller = controller

    def solve(self, problem: QPProblem):
        ctrl = self.controller
        targets = ctrl.wrench_targets
        if targets is None or ctrl.wrench_target_weight <= 0.0:
            return self.solver.solve(problem)
        active = [s for s in Side if ctrl.contacts[s].active]
        nv = ctrl.nv
        H, g = problem.H, problem.g
        if H.shape[0] != nv + 6 * len(active):  # not the layout this wrapper knows: leave the problem alone
            ctrl.n_wrench_target_skipped += 1
            return self.solver.solve(problem)
        H = H.copy()
        g = g.copy()
        w = ctrl.wrench_target_weight
        for i, s in enumerate(active):
            k = nv + 6 * i
            H.flat[k * (H.shape[0] + 1): (k + 6) * (H.shape[0] + 1): H.shape[0] + 1] += w
            g[k:k + 6] -= w * targets[s]
        return self.solver.solve(QPProblem._trusted(H, g, problem.A_eq, problem.b_eq, problem.C, problem.l,
                                                    problem.u, problem.lb, problem.ub))

    def __getattr__(self, name):
        return getattr(self.solver, name)


@register
class TSIDTeleop(InverseDynamicsController):
    """Teleoperation controller (module docstring).

    Args:
        robot, mode, dt: as every controller.
        taskset: a task set (default: `teleop_taskset(robot, repulsors=repulsors)`).
        repulsors: keep the task set's self_collision tasks (ignored when `taskset` is given).
        stabilizer: apply the task set's `teleop_stabilizer` (paper Eq. 2-7) when it has one.
    """

    name = "tsid-teleop"
    default_mode = ActuationMode.SPD
    modes = (ActuationMode.SPD, ActuationMode.POSITION, ActuationMode.TORQUE)

    def __init__(self, robot: Robot, mode: ActuationMode, dt: float, taskset: TaskSetSpec | None = None, *,
                 repulsors: bool = True, stabilizer: bool = True):
        spec = taskset if taskset is not None else teleop_taskset(robot, repulsors=repulsors)
        super().__init__(robot, ActuationMode(mode), dt, spec)
        self.repulsors = any(t.type == "self_collision" for t in spec.tasks)
        self.collision_tasks = [t for t in self.tasks if type(t).__name__ == "SelfCollisionTask"]
        self.teleop_stabilizer = None
        teleop = spec.teleop
        st_spec = teleop.stabilizer if teleop is not None else None
        if stabilizer and st_spec is not None and st_spec.enabled:
            from ..stabilizers.teleop import TeleopStabilizer

            self.teleop_stabilizer = TeleopStabilizer(robot, st_spec, dt)
        self.wrench_targets: dict[Side, np.ndarray] | None = None
        self.wrench_target_weight = teleop.wrench_regularization if teleop is not None else 0.0
        self.n_wrench_target_skipped = 0
        self.n_torque_rows_dropped = 0
        self._sole_center = np.array([*robot.profile.sole.center, 0.0])
        self._feet_nominal: dict = {}
        self._targets_key = None
        self._targets_cache = None
        self.solver = _WrenchTargetSolver(self.solver, self)
        self.relaxed_solver = _WrenchTargetSolver(self.relaxed_solver, self)
        self.torque_solver = _WrenchTargetSolver(self.torque_solver, self)
        self._target_log = np.full(9, np.nan)
        self._collision_log = np.full(2, np.nan)

    def reset(self, meas: Measurement, refs: References) -> None:
        super().reset(meas, refs)
        # the static split of the weight between the active contacts, the first tick's "previous wrench"
        active = [s for s in Side if self.contacts[s].active]
        for s in Side:
            self.wrench[s] = np.zeros(6)
            if s in active:
                self.wrench[s][2] = self.robot.mass * 9.81 / len(active)
        self.wrench_targets = None
        self._feet_nominal = {s: pin.SE3(cs.contact.reference) for s, cs in self.contacts.items()
                              if cs.contact.reference is not None}
        self._targets_key = None
        self._targets_cache = None
        if self.teleop_stabilizer is not None:
            self.teleop_stabilizer.reset(self)

    def step(self, meas: Measurement, refs: References) -> Command:
        self.wrench_targets = None
        if self.teleop_stabilizer is not None:
            refs = self.teleop_stabilizer.correct(meas, refs, self)
        if self.wrench_targets is None and self.wrench_target_weight > 0.0:
            self.wrench_targets = self._reference_targets(refs)
        for i, name in enumerate(("left_hand", "right_hand", "head")):
            target = refs.targets.get(name)
            if target is not None:
                M = target[0] if isinstance(target, tuple) else target
                self._target_log[3 * i:3 * i + 3] = M.translation
        return super().step(meas, refs)

    def _reference_targets(self, refs: References) -> dict[Side, np.ndarray] | None:
        """F of Eq. 7 for the active contacts at their nominal (reset) poses, cached while the CoM reference and
        the active contacts stay the same."""
        from ..stabilizers.teleop import reference_wrench_targets

        active = tuple(s for s in Side if self.contacts[s].active)
        if not active or refs.com is None:
            return None
        acc = refs.com_acc if refs.com_acc is not None else np.zeros(3)
        key = (active, refs.com.tobytes(), acc.tobytes())
        if key != self._targets_key:
            feet = {s: self._feet_nominal[s] if s in self._feet_nominal else self.contacts[s].contact.reference
                    for s in active}
            self._targets_cache = reference_wrench_targets(refs.com, acc, feet, self._sole_center, self.robot.mass)
            self._targets_key = key
        return self._targets_cache

    def _solve_limited(self, L, res, t0: float):
        """The first QP (joint limits, no torque rows) is solved but its torques exceed a limit. In SPD and
        position modes the QP's torques are not sent to the robot (joint references are), so when the QP with
        the torque rows is infeasible its solution is kept, rather than the base class's relaxed QP that also
        drops the joint limits. Fast replays hit this every tick (90 % of the ticks of a bimanual push-pull at
        x2): without joint limits the model pitched its pelvis by 0.5 rad, and `waving` replayed 3.5 and 4 times
        faster fell (stabilizer off); with this fallback both stand (x4.5 still falls). Counted in
        `qp_torque_rows_dropped_ticks`."""
        if self.mode is ActuationMode.TORQUE or not res.ok:
            return super()._solve_limited(L, res, t0)
        self._fill_torque_rows(L)
        limited = self.torque_solver.solve(L.problem_torque)
        self._t_solve = perf_counter() - t0
        self.qp_status = QP_OK
        if limited.ok:
            return limited.x, L.torques(limited.x)
        self.n_torque_rows_dropped += 1
        return res.x, L.torques(res.x)

    def _set_references(self, refs: References) -> None:
        super()._set_references(refs)
        if self.teleop_stabilizer is not None:
            self.teleop_stabilizer.apply_to_contacts(self)

    # ------------------------------------------------------------------ logging
    def log_channels(self) -> dict[str, list[str]]:
        ch = super().log_channels()
        ch["teleop_target"] = [f"{e}_{a}" for e in ("left_hand", "right_hand", "head") for a in "xyz"]
        ch["repulsor_max"] = ["left", "right"]
        if self.teleop_stabilizer is not None:
            ch["teleop_stabilizer"] = list(self.teleop_stabilizer.LOG_LABELS)
        return ch

    def log_values(self) -> list:
        vals = super().log_values()
        for i, task in enumerate(self.collision_tasks[:2]):
            self._collision_log[i] = float(np.max(task.values(self.model, self.data)))
        vals += [self._target_log, self._collision_log]
        if self.teleop_stabilizer is not None:
            vals.append(self.teleop_stabilizer.log)
        return vals

    def status(self) -> dict:
        out = super().status()
        out["repulsors"] = self.repulsors
        out["stabilizer"] = self.teleop_stabilizer is not None
        out["qp_torque_rows_dropped_ticks"] = self.n_torque_rows_dropped
        if self.n_wrench_target_skipped:
            out["wrench_target_skipped_ticks"] = self.n_wrench_target_skipped
        return out
