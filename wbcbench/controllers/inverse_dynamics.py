"""Task-space inverse dynamics as one weighted QP (TSID-like), paper 000 Sections 3.2-3.3.

Decision variables x = [dv (nv); w_1 (6); ...; w_k (6)]: joint accelerations and one wrench per active sole
contact (LOCAL sole frame, at its origin, exerted by the ground on the robot).

    min   sum_i w_i || A_i dv - b_i ||^2  + r_dv ||dv||^2 + r_w ||w||^2           (priority-1 tasks)
    s.t.  M_b dv + h_b = J_c,b^T w                    floating-base rows of the dynamics (6)
          J_c dv = -J_c_dot v + Kp e_c - Kd J_c v     rigid contacts (6 per contact)
          A_j dv = b_j                                priority-0 tasks, if any
          C w <= u                                    friction pyramid, CoP in the sole, f_min <= f_z <= f_max
          a_min <= dv_joints <= a_max                 joint position and velocity limits as acceleration bounds
          -tau_max <= M_a dv + h_a - J_c,a^T w <= tau_max   torque limits

Torque mode: tau = M_a dv + h_a - J_c,a^T w, computed on the measured state every tick.
Position mode: dv is integrated twice on the manifold, the integrated state (not the measured one) feeds the
next QP (Section 3.3), and (q, v) of the integrated state go to the joint servos.

If the QP fails, it is solved again without the joint-limit and torque-limit rows (the robot's safety is
better served by a slightly violated limit than by no command). If that fails too, the safe fallback is used:
torque mode sends the joint-pd law (PD to the current posture plus gravity and contact compensation), position
mode holds the last integrated posture with zero velocity. Both events are counted and logged per tick.
"""

from __future__ import annotations

from time import perf_counter

import numpy as np
import pinocchio as pin

from ..qp.problem import QPProblem
from ..qp.registry import make_solver
from ..robots import Robot, Side
from ..sim.model import ActuationMode
from ..stabilizers.balance import BalanceStabilizer
from ..tasks import (AngularMomentumTask, CoMTask, Contact6D, FrameTask, PostureTask, acceleration_rows,
                     update_kinematics)
from ..types import Command, Measurement, References
from .base import Controller, register
from .taskset import TaskSetSpec, TaskSpec, load_taskset, taskset_path

QP_OK, QP_RELAXED, QP_FALLBACK = 0, 1, 2


def build_task(robot: Robot, spec: TaskSpec):
    """A task object of the task library from its spec."""
    m = robot.model
    if spec.type == "com":
        return CoMTask(m, name=spec.name, weight=spec.weight, kp=spec.kp, kd=spec.kd, mask=spec.mask)
    if spec.type == "frame":
        return FrameTask(m, spec.frame, name=spec.name, weight=spec.weight, kp=spec.kp, kd=spec.kd,
                         mask=spec.mask)
    if spec.type == "posture":
        return PostureTask(m, name=spec.name, weight=spec.weight, kp=spec.kp, kd=spec.kd,
                           joints=robot.joint_names)
    if spec.type == "angular_momentum":
        # the paper's "Kp am" is the rate gain of dh = -Kp h, the task library's kd
        return AngularMomentumTask(m, name=spec.name, weight=spec.weight, kd=spec.kp, mask=spec.mask)
    raise ValueError(f"unknown task type {spec.type}")


class _ContactState:
    """A sole contact and its force ramp (the maximum normal force goes to 0 before the contact is removed)."""

    def __init__(self, contact: Contact6D):
        self.contact = contact
        self.active = True
        self.ramp_from = contact.nominal_max_normal_force
        self.ramp_to = contact.nominal_max_normal_force
        self.ramp_t0 = 0.0
        self.ramp_T = 0.0

    def start_ramp(self, t: float, f_from: float, f_to: float, duration: float) -> None:
        self.ramp_from, self.ramp_to, self.ramp_t0, self.ramp_T = f_from, f_to, t, duration

    def update(self, t: float) -> bool:
        """Set the current max force; True when a ramp to zero has finished."""
        if self.ramp_T <= 0:
            s = 1.0
        else:
            s = min(1.0, max(0.0, (t - self.ramp_t0) / self.ramp_T))
        f = self.ramp_from + s * (self.ramp_to - self.ramp_from)
        if f != self.contact.max_normal_force:
            self.contact.set_max_force(f)
        return s >= 1.0 and self.ramp_to == 0.0


class InverseDynamicsController(Controller):
    """TSID-like weighted-QP inverse dynamics; see the module docstring."""

    modes = (ActuationMode.TORQUE, ActuationMode.POSITION, ActuationMode.SPD)

    def __init__(self, robot: Robot, mode: ActuationMode, dt: float, taskset: TaskSetSpec | None = None):
        super().__init__(robot, mode, dt)
        self.spec = taskset or load_taskset(taskset_path(robot, self.name), robot)
        self.model = robot.model
        self.data = robot.model.createData()
        m = self.model
        self.nv = m.nv
        self.tasks = [build_task(robot, t) for t in self.spec.tasks]
        self.task_by_name = {t.name: t for t in self.tasks}
        self.hard = {t.name for t in self.spec.tasks if t.priority == 0}
        c = self.spec.contacts
        sole = robot.profile.sole
        length, width = c.model_sole or (sole.length, sole.width)
        self.contacts = {
            s: _ContactState(Contact6D(m, robot.profile.feet[s].frame, length=length, width=width,
                                       center=sole.center, kp=c.kp, kd=c.kd, mu=c.mu,
                                       min_normal_force=c.min_normal_force, max_normal_force=c.max_normal_force,
                                       name=f"contact_{s.value}"))
            for s in Side}
        sw = self.spec.swing_foot
        self.swing = {s: FrameTask(m, robot.profile.feet[s].frame, name=f"swing_{s.value}", weight=sw.weight,
                                   kp=sw.kp, kd=sw.kd, mask=sw.mask) for s in Side}
        self.solver = make_solver(self.spec.solver)
        self.relaxed_solver = make_solver(self.spec.solver)
        self.torque_solver = make_solver(self.spec.solver)
        lo, hi = robot.position_limits
        self.q_lo, self.q_hi = lo, hi
        self.v_max = robot.velocity_limit
        self.tau_max = robot.effort_limit
        self.fallback_pd = None
        self._buf: dict[int, dict] = {}
        self._Jc: list[np.ndarray] = []
        self._t_pin = self._t_solve = 0.0
        max_rows = sum(t.dim for t in self.tasks) + 12
        self._Ac = np.zeros((max_rows, self.nv))
        self._bc = np.zeros(max_rows)
        self.n_relaxed = 0
        self.n_fallback = 0
        self.qp_status = QP_OK
        self.tau = np.zeros(robot.na)
        self.wrench = {s: np.zeros(6) for s in Side}
        self.dv = np.zeros(self.nv)
        self.q_int = None
        self.v_int = None
        self.t = 0.0
        self.stabilizer = None
        if self.spec.stabilizer is not None and mode is not ActuationMode.TORQUE:
            self.stabilizer = BalanceStabilizer(robot, self.spec.stabilizer, dt)

    # ------------------------------------------------------------------ lifecycle
    def reset(self, meas: Measurement, refs: References) -> None:
        q, v = meas.q.copy(), meas.v.copy()
        self.q_int, self.v_int = q.copy(), np.zeros(self.nv) if self.mode is not ActuationMode.TORQUE else v
        m, d = self.model, self.data
        update_kinematics(m, d, q, np.zeros(self.nv))
        if self.stabilizer is not None:
            self.stabilizer.reset(q)
        for t in self.tasks:
            if isinstance(t, PostureTask):
                t.set_reference(self.robot.q0)
            elif isinstance(t, AngularMomentumTask):
                t.set_reference()
            else:
                t.set_reference_to_current(m, d)
        self.com_task_refs = [t for t in self.tasks if isinstance(t, CoMTask)]
        for s, cs in self.contacts.items():
            cs.contact.set_reference_to_current(m, d)
            cs.active = s in refs.contacts
            cs.start_ramp(0.0, cs.contact.nominal_max_normal_force, cs.contact.nominal_max_normal_force, 0.0)
        for s, sw in self.swing.items():
            sw.set_reference_to_current(m, d)
        from .joint_pd import JointPD
        self.fallback_pd = JointPD(self.robot, ActuationMode.TORQUE, self.dt)

    def _state(self, meas: Measurement) -> tuple[np.ndarray, np.ndarray]:
        if self.mode is ActuationMode.TORQUE:
            return meas.q, meas.v
        return self.q_int, self.v_int

    # ------------------------------------------------------------------ contact schedule
    def _update_contacts(self, t: float, refs: References) -> None:
        m, d = self.model, self.data
        T = self.spec.contacts.transition_time
        for s, cs in self.contacts.items():
            wanted = s in refs.contacts
            if cs.active and not wanted and cs.ramp_to != 0.0:
                # start breaking the contact: ramp its max force from the current load to zero
                f_now = max(self.wrench[s][2], 0.0)
                cs.start_ramp(t, min(f_now, cs.contact.nominal_max_normal_force), 0.0, T)
            elif wanted and (not cs.active or cs.ramp_to == 0.0):
                # make (or keep) the contact: reference = where the foot is now (the model's foot in position
                # mode), maximum force ramped in from zero
                if not cs.active:
                    cs.contact.set_reference_to_current(m, d)
                cs.active = True
                cs.start_ramp(t, cs.contact.max_normal_force if cs.ramp_to == 0.0 else 0.0,
                              cs.contact.nominal_max_normal_force, T)
            if cs.active and cs.update(t):
                cs.active = False
                self.swing[s].set_reference_to_current(m, d)

    # ------------------------------------------------------------------ one tick
    def step(self, meas: Measurement, refs: References) -> Command:
        m, d = self.model, self.data
        t = meas.t
        q, v = self._state(meas)
        t0 = perf_counter()
        update_kinematics(m, d, q, v)
        self._t_pin = perf_counter() - t0
        if self.stabilizer is not None:
            refs = self.stabilizer.correct(meas, refs, self.q_int)
        self._set_references(refs)
        self._update_contacts(t, refs)
        active = [s for s in Side if self.contacts[s].active]
        x = self._solve(q, v, active)
        nv = self.nv
        if x is None:
            return self._fallback(meas, active)
        dv = x[:nv]
        self.dv = dv
        for s in Side:
            self.wrench[s][:] = 0.0
        for i, s in enumerate(active):
            self.wrench[s] = x[nv + 6 * i: nv + 6 * i + 6]
        tau = d.M[6:] @ dv + d.nle[6:]
        for i, s in enumerate(active):
            tau -= self._Jc[i][:, 6:].T @ self.wrench[s]
        self.tau = tau
        if self.mode is ActuationMode.TORQUE:
            return Command(tau=tau)
        self.v_int = self.v_int + dv * self.dt
        self.q_int = pin.integrate(m, self.q_int, self.v_int * self.dt)
        return Command(q=self.q_int[7:].copy(), v=self.v_int[6:].copy())

    def _set_references(self, refs: References) -> None:
        if refs.com is not None:
            for t in self.com_task_refs:
                t.set_reference(refs.com, refs.com_vel if refs.com_vel is not None else np.zeros(3),
                                refs.com_acc if refs.com_acc is not None else np.zeros(3))
        for name, target in refs.targets.items():
            task = self.task_by_name.get(name)
            if task is None:
                continue
            if isinstance(target, tuple):
                task.set_reference(*target)
            else:
                task.set_reference(target)
        for s, (p, vel, acc) in refs.feet.items():
            sw = self.swing[s]
            R = refs.feet_rotation.get(s, sw.reference.rotation)
            sw.set_reference(pin.SE3(R, np.asarray(p)), np.concatenate([vel, np.zeros(3)]),
                             np.concatenate([acc, np.zeros(3)]))

    def _buffers(self, nc: int) -> dict:
        """Preallocated QP arrays for `nc` active contacts (allocated once per contact count)."""
        buf = self._buf.get(nc)
        if buf is None:
            nv, na = self.nv, self.robot.na
            n = nv + 6 * nc
            n_eq = 6 + 6 * nc + sum(len(t.rows) for t in self.tasks if t.name in self.hard)
            buf = {
                "H": np.zeros((n, n)), "g": np.zeros(n),
                "A_eq": np.zeros((n_eq, n)), "b_eq": np.zeros(n_eq),
                "C": np.zeros((18 * nc + na, n)),
                "l": np.concatenate([np.full(18 * nc, -np.inf), np.zeros(na)]),
                "u": np.zeros(18 * nc + na),
                "lb": np.full(n, -np.inf), "ub": np.full(n, np.inf),
                "reg": np.concatenate([np.full(nv, self.spec.regularization_dv),
                                       np.full(6 * nc, self.spec.regularization_wrench)]),
            }
            self._buf[nc] = buf
        return buf

    def _solve(self, q: np.ndarray, v: np.ndarray, active: list[Side]) -> np.ndarray | None:
        m, d = self.model, self.data
        nv, nc = self.nv, len(active)
        na = nv - 6
        n = nv + 6 * nc
        B = self._buffers(nc)
        H, g, A_eq, b_eq, C, lo, hi, lb, ub = (B[k] for k in ("H", "g", "A_eq", "b_eq", "C", "l", "u", "lb", "ub"))
        # ---- cost: stack sqrt(w)-scaled rows, one product for the Hessian
        Ac, bc = self._Ac, self._bc
        k = 0
        hard_A, hard_b = [], []
        swing = [self.swing[s] for s in Side if not self.contacts[s].active]
        for task in self.tasks + swing:
            if task.weight == 0.0 and task.name not in self.hard:
                continue
            A, b = acceleration_rows(task, m, d)
            if task.name in self.hard:
                hard_A.append(A)
                hard_b.append(b)
                continue
            r = A.shape[0]
            sw = np.sqrt(task.weight)
            np.multiply(A, sw, out=Ac[k:k + r])
            np.multiply(b, -sw, out=bc[k:k + r])
            k += r
        H[:] = 0.0
        np.matmul(Ac[:k].T, Ac[:k], out=H[:nv, :nv])
        H.flat[::n + 1] += B["reg"]
        g[:] = 0.0
        np.matmul(Ac[:k].T, bc[:k], out=g[:nv])
        # ---- equalities: floating-base dynamics, contact motion, hard tasks
        A_eq[:] = 0.0
        A_eq[:6, :nv] = d.M[:6]
        b_eq[:6] = -d.nle[:6]
        # ---- inequalities: wrench cones (torque limits added lazily below); bounds: joint limits
        C[:18 * nc] = 0.0
        Jc = self._Jc
        Jc.clear()
        r = 6
        for i, s in enumerate(active):
            c = self.contacts[s].contact
            A, b = acceleration_rows(c, m, d)
            Jc.append(A)
            cols = slice(nv + 6 * i, nv + 6 * i + 6)
            A_eq[:6, cols] = -A[:, :6].T
            A_eq[r:r + 6, :nv] = A
            b_eq[r:r + 6] = b
            r += 6
            Cr, ur = c.force_rows()
            C[18 * i:18 * i + 18, cols] = Cr
            hi[18 * i:18 * i + 18] = ur
        for A, b in zip(hard_A, hard_b):
            A_eq[r:r + A.shape[0], :nv] = A
            b_eq[r:r + A.shape[0]] = b
            r += A.shape[0]
        qj, vj = q[7:], v[6:]
        h = self.spec.joint_limit_horizon
        a_hi = np.minimum(2 * (self.q_hi - qj - vj * h) / h**2, (self.v_max - vj) / self.dt)
        a_lo = np.maximum(2 * (self.q_lo - qj - vj * h) / h**2, (-self.v_max - vj) / self.dt)
        lb[6:nv] = np.minimum(a_lo, a_hi)
        ub[6:nv] = a_hi
        k = 18 * nc
        cones = (C[:k], lo[:k], hi[:k]) if nc else (None, None, None)
        t0 = perf_counter()
        # Torque limits are lazy constraints: solve without them, and only if the optimum violates one solve
        # again with all of them (then the optimum is exactly the full problem's).
        res = self.solver.solve(QPProblem._trusted(H, g, A_eq, b_eq, *cones, lb, ub))
        if res.ok:
            tau = d.M[6:] @ res.x[:nv] + d.nle[6:]
            for i in range(nc):
                tau -= Jc[i][:, 6:].T @ res.x[nv + 6 * i: nv + 6 * i + 6]
            if np.all(np.abs(tau) <= self.tau_max * (1 + 1e-9)):
                self._t_solve = perf_counter() - t0
                self.qp_status = QP_OK
                return res.x
            C[k:] = 0.0
            C[k:, :nv] = d.M[6:]
            for i in range(nc):
                C[k:, nv + 6 * i: nv + 6 * i + 6] = -Jc[i][:, 6:].T
            lo[k:] = -self.tau_max - d.nle[6:]
            hi[k:] = self.tau_max - d.nle[6:]
            res = self.torque_solver.solve(QPProblem._trusted(H, g, A_eq, b_eq, C, lo, hi, lb, ub))
        self._t_solve = perf_counter() - t0
        if res.ok:
            self.qp_status = QP_OK
            return res.x
        # relaxed: keep the contact rows, drop joint and torque limits
        self.n_relaxed += 1
        res = self.relaxed_solver.solve(QPProblem._trusted(H, g, A_eq, b_eq, *cones))
        if res.ok:
            self.qp_status = QP_RELAXED
            return res.x
        self.n_fallback += 1
        self.qp_status = QP_FALLBACK
        return None

    def _fallback(self, meas: Measurement, active: list[Side]) -> Command:
        if self.mode is ActuationMode.TORQUE:
            self.fallback_pd.q_ref = meas.q[7:].copy()
            cmd = self.fallback_pd.step(meas, References(t=meas.t, contacts=frozenset(active)))
            self.tau = cmd.tau
            return cmd
        self.v_int = np.zeros(self.nv)
        return Command(q=self.q_int[7:].copy(), v=np.zeros(self.robot.na))

    # ------------------------------------------------------------------ logging
    @property
    def last_timing_us(self) -> dict[str, float]:
        """Split of the last step [us]: pinocchio (kinematics and dynamics update) and the QP solve; the rest
        of a step is task rows, QP assembly and the command."""
        return {"pinocchio": self._t_pin * 1e6, "solve": self._t_solve * 1e6}

    def log_channels(self) -> dict[str, list[str]]:
        w = ["fx", "fy", "fz", "mx", "my", "mz"]
        return {"qp_status": [], "tau_cmd": self.robot.joint_names,
                "stabilizer": BalanceStabilizer.LOG_LABELS,
                "wrench_qp_left": w, "wrench_qp_right": w,
                "contact_active": ["left", "right"]}

    def log_values(self) -> list:
        stab = self.stabilizer.log if self.stabilizer is not None else np.full(6, np.nan)
        return [self.qp_status, self.tau, stab, self.wrench[Side.LEFT], self.wrench[Side.RIGHT],
                [float(self.contacts[s].active) for s in Side]]

    def status(self) -> dict:
        return {"qp_relaxed_ticks": self.n_relaxed, "qp_fallback_ticks": self.n_fallback}


@register
class TSIDTorque(InverseDynamicsController):
    name = "tsid-torque"
    default_mode = ActuationMode.TORQUE


@register
class TSIDPosition(InverseDynamicsController):
    name = "tsid-position"
    default_mode = ActuationMode.POSITION
    modes = (ActuationMode.POSITION, ActuationMode.SPD)
