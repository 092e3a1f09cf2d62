"""`tsid-teleop`: the TSID-like weighted QP with the teleoperation task set (paper 004 Table I), the
self-collision repulsors (Eq. 8-13) and the force-based stabilizer (Eq. 2-7) in front.

It is `InverseDynamicsController` (inverse_dynamics.py) with its own policy:

* the task set is `tasksets/<robot>/teleop.yaml` (Table I); `repulsors=False` drops its `self_collision`
  tasks (the paper's Table II condition); its `stabilizer: {type: force}` is `TeleopStabilizer`
  (wbcbench/stabilizers/teleop.py), which corrects the CoM reference (Eq. 2), the contact (ankle) orientations
  (Eq. 3), the torso roll (Eq. 4-5) and gives wrench targets from the ZMP distributor (Eq. 6-7);
* wrench targets: the formulation regularises each contact wrench towards a target with the task set's
  `regularization.wrench_target` weight (the paper's contact force regularisation task): F* of Eq. 7 when the
  stabilizer's ZMP distributor runs, else F, the split of the reference ZMP between the feet (Eq. 6 on the CoM
  reference's cart-table ZMP, `reference_wrench_targets`). In position and SPD modes the split between the feet
  is not determined by the motion: without a target it drifts from tick to tick, and the foot force difference
  (Eq. 4-5) and CoM admittance (Eq. 2), which compare it with the measured forces, wind up;
* when the torque-limited QP is infeasible in SPD and position modes the joint-limited solution is kept
  (`_solve_limited`);
* SPD and position modes: each arm joint's acceleration is bounded by what a share of its torque limit gives it
  (`_solve`, `arm_acceleration_bounds`), so that the integrated arm, which the joint servos follow, moves only as
  fast as the arm's actuators can follow it;
* out-of-reach caps: while a hand's or the head's position error exceeds the task set's `reach_cap.error[0]` (TALOS:
  10 cm; the arm at its joint limits, or far behind a target it cannot follow) and its reference moves (from
  `speed[0]`, 0.2 m/s), its task's commanded acceleration is scaled down to `reach_cap.linear` / `angular` (20
  m/s^2, 60 rad/s^2), fully from `error[1]` and `speed[1]` on (`InverseDynamicsFormulation.set_acceleration_caps`).
  With kp 8000, an arm that cannot follow its target asked for hundreds of m/s^2 and the weighted QP took them from
  the torso, the pelvis and the legs: on public dance, jump and spin captures the model bent over its straightened
  legs until the pelvis tilted 0.7 rad, with the feet flat on the ground. The cap leaves a tracked target (errors of
  a few cm) and a still one untouched. The angular cap also applies while a hand's rotation error exceeds
  `reach_cap.rotation[0]` (TALOS: 0.10 rad; fully from `rotation[1]`, 0.20 rad), whatever its reference's speed,
  while its position error is under `rotation_within` (0.20-0.30 m: a hand held off a reference inside the body by
  the repulsors keeps its full angular demand), its linear acceleration left alone: an operator's wrist turns at up
  to 12 rad/s, TALOS' at about 2, and the QP turned the gripper with the shoulder and elbow at their torque limits,
  swinging it tens of cm off its position reference (gated by the reference's angular speed as well, the cap let go
  while the error was large, and the real squat capture fell);
* SPD and position modes, the task set's `arm_damping_injection` c > 0: the arms' velocity references are
  ``v_int + c (v_int - v)`` (v the encoders' velocities, `inject_damping`), so that the joint servos, whose
  damping is only 0.01 of their stiffness, damp the arm's tracking error (1 + c) times as much.

Default mode: SPD (stable PD at the joints, as the paper in simulation); position and torque also work.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from time import perf_counter

import numpy as np
import pinocchio as pin

from ..errors import ConfigError
from ..jit import njit
from ..qp.active_set_guess import ActiveSetGuessSolver
from ..qp.registry import make_solver
from ..robots import Robot, Side
from ..stabilizers.teleop import reference_split, reference_wrench_targets
from ..tasks import SelfCollisionTask
from ..types import GRAVITY, ActuationMode, Command, Measurement, References
from .inverse_dynamics import QP_OK, InverseDynamicsController
from .taskset import TaskSetSpec, load_taskset, taskset_path

__all__ = ["TSIDTeleop", "arm_acceleration_bounds", "arm_joints", "inject_damping", "teleop_taskset"]

_LEFT, _RIGHT = Side.LEFT, Side.RIGHT


@njit(exact=True)
def _max(x: np.ndarray) -> float:
    """np.max of a non-empty 1-D array (NaN if any element is), without numpy's reduction machinery."""
    m = x[0]
    for i in range(x.shape[0]):
        v = x[i]
        if np.isnan(v):
            return v
        if v > m:
            m = v
    return m


@njit(exact=True)
def _max2(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """``out[:] = _max(a), _max(b)`` in one call."""
    out[0] = _max(a)
    out[1] = _max(b)


@njit(exact=True)
def arm_acceleration_bounds(M, nle, idx, tau_max, share, lb, ub, saved):
    """Per arm joint k (velocity index ``idx[k]``, joint index ``idx[k] - 6`` of ``tau_max``, ``lb``, ``ub``):
    the acceleration bounds ``(+-share tau_max - h) / M_kk`` at the QP's state (``M``, ``nle``: pinocchio's
    mass matrix and nonlinear effects), intersected with the joint-limit bounds ``lb``, ``ub`` (na,) in place;
    where the intersection is empty the joint-limit bounds are kept. The bounds replaced go to ``saved`` (2, k)."""
    for k in range(idx.shape[0]):
        i = idx[k]
        j = i - 6
        lo, hi = lb[j], ub[j]
        saved[0, k], saved[1, k] = lo, hi
        t = share * tau_max[j]
        m = M[i, i]
        a_lo = (-t - nle[i]) / m
        a_hi = (t - nle[i]) / m
        if a_lo > lo:
            lo = a_lo
        if a_hi < hi:
            hi = a_hi
        if lo <= hi:
            lb[j], ub[j] = lo, hi


@njit(exact=True)
def inject_damping(v_cmd, v_meas, idx, c):
    """``v_cmd[j] += c (v_cmd[j] - v_meas[j + 6])`` in place for the joints ``j = idx[k] - 6`` (``idx``: velocity
    indices; ``v_cmd`` (na,) the joints' velocity references, ``v_meas`` (nv,) the measured velocities)."""
    for k in range(idx.shape[0]):
        j = idx[k] - 6
        v_cmd[j] += c * (v_cmd[j] - v_meas[j + 6])


@njit(exact=True)
def _restore_bounds(idx, saved, lb, ub):
    """Undo `arm_acceleration_bounds`."""
    for k in range(idx.shape[0]):
        j = idx[k] - 6
        lb[j], ub[j] = saved[0, k], saved[1, k]


TASKSET_NAME = "teleop"


def arm_joints(robot: Robot) -> np.ndarray:
    """Velocity indices of the arms' joints: those that carry one gripper (the protected frame of a side's
    `repulsors` in the robot profile) and not the other, increasing."""
    model = robot.model
    idx = [model.joints[j].idx_v + k for j in sorted(robot.arm_joint_ids()) if j > 0
           for k in range(model.joints[j].nv)]
    return np.array(sorted(idx), dtype=np.intp)


def teleop_taskset(robot: Robot, *, repulsors: bool = True) -> TaskSetSpec:
    """The robot's teleoperation task set (tasksets/<robot>/teleop.yaml), without its self-collision tasks when
    `repulsors` is False."""
    spec = load_taskset(taskset_path(robot, TASKSET_NAME), robot)
    if not repulsors:
        spec = replace(spec, tasks=tuple(t for t in spec.tasks if t.type != "self_collision"))
    return spec


class TSIDTeleop(InverseDynamicsController):
    """Teleoperation controller (module docstring).

    Args:
        robot, mode, dt: as every controller.
        taskset: a task set (default: `teleop_taskset(robot, repulsors=repulsors)`).
        repulsors: keep the task set's self_collision tasks (ignored when `taskset` is given).
        stabilizer: apply the task set's `teleop_stabilizer` (paper Eq. 2-7) when it has one.
        arm_torque_share: SPD and position modes: bound each arm joint's acceleration by what this share of its
            torque limit gives it (default: the task set's `arm_torque_share`; 0: no bound, the integrated arm
            unbounded).
        reach_cap: apply the task set's out-of-reach caps (`reach_cap:`, `ReachCapSpec`) when it has them: the
            hands' and head's commanded accelerations capped while their targets are out of reach (default True).
    """

    name = "tsid-teleop"
    default_mode = ActuationMode.SPD
    modes = (ActuationMode.SPD, ActuationMode.POSITION, ActuationMode.TORQUE)
    #: daqp's iteration limit on the torque-limited QP in SPD and position modes (see `__init__`)
    TORQUE_QP_ITERATIONS = 60

    def __init__(self, robot: Robot, mode: ActuationMode, dt: float, taskset: TaskSetSpec | None = None, *,
                 repulsors: bool = True, stabilizer: bool = True, arm_torque_share: float | None = None,
                 reach_cap: bool = True):
        if isinstance(taskset, (str, Path)):
            taskset = load_taskset(taskset, robot)
        spec = taskset if taskset is not None else teleop_taskset(robot, repulsors=repulsors)
        if not stabilizer:
            spec = spec.without_stabilizer()
        super().__init__(robot, ActuationMode(mode), dt, spec)
        if self.mode is not ActuationMode.TORQUE and spec.solver == "daqp":
            # the torque-limited QP may fail here (`_solve_limited` keeps the joint-limited optimum), so it gets a
            # bounded time: daqp needed at most 30 iterations on the 524 of a reach_forward replay (median 12), but
            # cycled on a few ill-conditioned ones (10,000 iterations: 20-75 ms; 100: 0.7-1.9 ms)
            self.torque_solver = ActiveSetGuessSolver(make_solver("daqp", iter_limit=self.TORQUE_QP_ITERATIONS))
        self.repulsors = any(t.type == "self_collision" for t in spec.tasks)
        self.collision_tasks = [t for t in self.tasks if isinstance(t, SelfCollisionTask)]
        # the task set's out-of-reach caps (`reach_cap:`), unless switched off
        self.reach_cap = bool(reach_cap) and spec.reach_cap is not None
        if self.reach_cap:
            self.formulation.set_acceleration_caps(spec.reach_cap.tasks, spec.reach_cap.params())
        self.n_torque_rows_dropped = 0
        # SPD and position modes: the arms' joints (velocity indices), whose accelerations `_solve` bounds
        share = spec.arm_torque_share if arm_torque_share is None else float(arm_torque_share)
        if not (np.isfinite(share) and 0.0 <= share):
            raise ConfigError(f"arm_torque_share must be a finite number >= 0, got {arm_torque_share!r}",
                              key="arm_torque_share")
        self.arm_torque_share = share
        arms, none = arm_joints(robot), np.zeros(0, dtype=np.intp)
        self._arm_v = arms if self.mode is not ActuationMode.TORQUE and share > 0.0 else none
        self._arm_saved = np.zeros((2, self._arm_v.size))
        self.n_arm_bounds_dropped = 0
        # SPD and position modes: the gain c of the arms' velocity references on their tracking error (`step`)
        self.arm_damping_injection = (float(spec.arm_damping_injection) if self.mode is not ActuationMode.TORQUE
                                      else 0.0)
        self._arm_damped = arms if self.arm_damping_injection > 0.0 else none
        self._sole_center = np.array([*robot.profile.sole.center, 0.0])
        self._feet_nominal: dict = {}
        self._feet_nominal_arrays = None
        self._mass = float(robot.mass)
        self._targets_key = None
        self._targets_cache = None
        self._target_log = np.full(9, np.nan)
        self._collision_log = np.full(2, np.nan)

    def reset(self, meas: Measurement, refs: References) -> None:
        super().reset(meas, refs)
        # the static split of the weight between the active contacts, the first tick's "previous wrench"
        active = [s for s in Side if self.contacts[s].active]
        for s in Side:
            self.wrench[s] = np.zeros(6)
            if s in active:
                self.wrench[s][2] = self.robot.mass * GRAVITY / len(active)
        self._feet_nominal = {s: pin.SE3(cs.contact.reference) for s, cs in self.contacts.items()
                              if cs.contact.reference is not None}
        # both feet's nominal rotations and translations as arrays, for the usual tick (both feet down)
        self._feet_nominal_arrays = (tuple(a for s in Side for a in (self._feet_nominal[s].rotation,
                                                                     self._feet_nominal[s].translation))
                                     if len(self._feet_nominal) == 2 else None)
        self._targets_key = None
        self._targets_cache = None

    def step(self, meas: Measurement, refs: References) -> Command:
        for i, name in enumerate(("left_hand", "right_hand", "head")):
            target = refs.targets.get(name)
            if target is not None:
                self._target_log[3 * i:3 * i + 3] = target.position
        cmd = super().step(meas, refs)
        if self._arm_damped.size and cmd.v is not None:
            # the servos' torque kp (q_int - q) + kd (v_ref - v) with v_ref = v_int + c (v_int - v): the arm's
            # tracking error damped (1 + c) kd. The joint servos' kd is 0.01 kp: on fast real motions the saturated
            # arms lagged the integrated ones by 0.18 rad (median, punch in place) and overshot them into the thighs
            inject_damping(cmd.v, meas.v, self._arm_damped, self.arm_damping_injection)
        return cmd

    def _warm_up(self, meas: Measurement) -> None:
        dropped = self.n_torque_rows_dropped, self.n_arm_bounds_dropped, self.formulation.n_capped_ticks
        super()._warm_up(meas)
        self.n_torque_rows_dropped, self.n_arm_bounds_dropped, self.formulation.n_capped_ticks = dropped  # not a tick

    def _wrench_targets(self, refs: References) -> dict | None:
        """The stabilizer's F* (Eq. 7) when it gave them, else F (Eq. 6) of the reference ZMP."""
        if refs.wrench_targets:
            return refs.wrench_targets
        if self.formulation.wrench_target_weight > 0.0:
            return self._reference_targets(refs)
        return None

    def _reference_targets(self, refs: References) -> dict[Side, np.ndarray] | None:
        """F of Eq. 7 for the active contacts at their nominal (reset) poses, cached while the CoM reference and
        the active contacts stay the same."""
        active = self.formulation.active
        if not active or refs.com is None:
            return None
        com, acc = refs.com.position, refs.com.acceleration
        key = (active, com.tobytes(), acc.tobytes())
        if key != self._targets_key:
            nominal = self._feet_nominal_arrays
            if len(active) == 2 and nominal is not None:  # `reference_wrench_targets`' compiled case, directly
                out = np.empty((2, 6))
                reference_split(com, acc, *nominal, self._sole_center, self._mass, GRAVITY, out)
                self._targets_cache = {_LEFT: out[0], _RIGHT: out[1]}
            else:
                feet = {s: self._feet_nominal[s] if s in self._feet_nominal else self.contacts[s].contact.reference
                        for s in active}
                self._targets_cache = reference_wrench_targets(com, acc, feet, self._sole_center, self.robot.mass)
            self._targets_key = key
        return self._targets_cache

    def _first_solve(self, P):
        """SPD and position modes: the first solve with each arm joint's acceleration bounded by
        `arm_torque_share` of its torque limit, ``(+-share tau_max - h_i) / M_ii`` at the model's state
        (`arm_acceleration_bounds`). The joint servos get positions and velocities only and saturate at the arms'
        torque limits: with accelerations the arms cannot produce (the QP's arm torques reached up to 30 times the
        limits on fast real motions, the torque-limited QP being infeasible) the measured arm lagged the
        integrated one by up to 0.9 rad, then ran after it at saturated torque and overshot it, and the measured
        gripper hit the thigh while the model's stayed outside the repulsors. When the bounds conflict with
        another constraint (the QP is infeasible) the QP is solved without them (counted in
        `qp_arm_bounds_dropped_ticks`)."""
        idx = self._arm_v
        if not idx.size:
            return super()._first_solve(P)
        F = self.formulation
        L = F._layout
        d = F.data
        arm_acceleration_bounds(d.M, d.nle, idx, F.tau_max, self.arm_torque_share, L.lb_joints, L.ub_joints,
                                self._arm_saved)
        res = self.solve_qp(self.solver, P)
        if not res.ok:
            _restore_bounds(idx, self._arm_saved, L.lb_joints, L.ub_joints)
            self.n_arm_bounds_dropped += 1
            res = self.solve_qp(self.solver, P)
        return res

    def _solve_limited(self, res, t0: float):
        """The first QP (joint limits, no torque rows) is solved but its torques exceed a limit. In SPD and
        position modes the QP's torques are not sent to the robot (joint references are), so when the QP with
        the torque rows is infeasible its solution is kept, rather than the base class's relaxed QP that also
        drops the joint limits. Fast replays hit this every tick (90 % of the ticks of a bimanual push-pull at
        x2): without joint limits the model pitched its pelvis by 0.5 rad, and `waving` replayed 3.5 and 4 times
        faster fell (stabilizer off); with this fallback both stand (x4.5 still falls). Counted in
        `qp_torque_rows_dropped_ticks`."""
        if self.mode is ActuationMode.TORQUE or not res.ok:
            return super()._solve_limited(res, t0)
        F = self.formulation
        limited = self.solve_qp(self.torque_solver, F.problem_with_torque_limits())
        self._t_solve = perf_counter() - t0
        self.qp_status = QP_OK
        if limited.ok:
            return limited.x, F.torques(limited.x)[0]
        self.n_torque_rows_dropped += 1
        return res.x, F.torques(res.x)[0]

    # ------------------------------------------------------------------ logging
    def log_channels(self) -> dict[str, list[str]]:
        ch = super().log_channels()
        ch["teleop_target"] = [f"{e}_{a}" for e in ("left_hand", "right_hand", "head") for a in "xyz"]
        ch["repulsor_max"] = ["left", "right"]
        return ch

    def log_values(self) -> list:
        vals = super().log_values()
        out = self._collision_log
        tasks, m, d = self.collision_tasks, self.model, self.data
        # this tick's values: the tasks' cache of the step (their own arrays, not copied)
        if len(tasks) >= 2:
            _max2(tasks[0].values(m, d, copy=False), tasks[1].values(m, d, copy=False), out)
        else:
            for i, task in enumerate(tasks):
                out[i] = _max(task.values(m, d, copy=False))
        vals += [self._target_log, out]
        return vals

    def status(self) -> dict:
        out = super().status()
        out["repulsors"] = self.repulsors
        out["stabilizer"] = self.stabilizer is not None
        out["qp_torque_rows_dropped_ticks"] = self.n_torque_rows_dropped
        out["qp_arm_bounds_dropped_ticks"] = self.n_arm_bounds_dropped
        out["arm_damping_injection"] = self.arm_damping_injection
        out["reach_capped_ticks"] = self.formulation.n_capped_ticks
        return out
