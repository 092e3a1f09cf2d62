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

from ..qp import _jit
from ..qp.active_set_guess import ActiveSetGuessSolver
from ..qp.problem import QPProblem
from ..qp.registry import make_solver
from ..robots import Robot, Side
from ..sim.model import ActuationMode
from ..estimation.base_feedback import BaseFeedback
from ..stabilizers.balance import BalanceStabilizer
from ..tasks import AngularMomentumTask, CoMTask, Contact6D, FrameTask, PostureTask, TaskStack, update_kinematics
from ..types import Command, Measurement, References
from . import _kernels
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
    if spec.type == "self_collision":
        from ..tasks import RepulsionPoint, SelfCollisionTask

        rep = spec.repulsors
        points = [RepulsionPoint(p.frame, p.radius, p.offset, p.name) for p in rep.points]
        return SelfCollisionTask(m, rep.frame, points, radius=rep.radius, offset=rep.offset, exponent=rep.exponent,
                                 normalized=rep.normalized, kp=spec.kp, kd=spec.kd, weight=spec.weight,
                                 mask=spec.mask, name=spec.name)
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


class _QPLayout:
    """Named views of the QP buffers and of the task stack's rows for one set of active contacts and one stack
    layout, made once, so that a tick only computes (x = [dv; w_1; ...], rows of the stack: contacts, hard tasks,
    then the weighted tasks). The QPProblem objects are built once too: their arrays are refilled in place."""

    __slots__ = ("slices", "k", "Aw", "bw", "A_cost", "b_cost", "sw", "Jc", "sw_column", "minus_sw", "H_dv", "H_diag_dv",
                 "g_dv", "A_eq_M", "A_eq_w", "A_eq_J", "b_eq_h", "b_eq_J", "A_hard", "b_hard", "Jc_base_T",
                 "Jc_joints_T", "M_base", "M_joints", "nle_base", "nle_joints", "cones", "C_blocks", "u_blocks",
                 "C", "l", "u", "lb_joints", "ub_joints", "problem", "problem_torque", "problem_relaxed")

    def __init__(self, ctrl: InverseDynamicsController, active: tuple[Side, ...], stack: TaskStack, n_hard: int,
                 A: np.ndarray, b: np.ndarray):
        nv, nc, d = ctrl.nv, len(active), ctrl.data
        self.slices = stack.slices
        me = self.slices[n_hard - 1].stop if n_hard else 0
        B = ctrl._buffers(nc, 6 + me)
        H, g, A_eq, b_eq, C, lo, hi, lb, ub = (B["H"], B["g"], B["A_eq"], B["b_eq"], B["C"], B["l"], B["u"],
                                               B["lb"], B["ub"])
        sw = stack.sqrt_weights[me:]
        self.A_cost, self.b_cost = A[me:], b[me:]
        self.sw, self.sw_column, self.minus_sw = sw, sw[:, None], -sw
        self.Aw, self.bw = np.empty(self.A_cost.shape), np.empty(self.b_cost.shape)
        self.H_dv, self.H_diag_dv, self.g_dv = B["H_dv"], B["H_diag_dv"], B["g_dv"]
        self.A_eq_M, self.A_eq_w, self.A_eq_J = A_eq[:6, :nv], A_eq[:6, nv:], A_eq[6:, :nv]
        self.b_eq_h, self.b_eq_J = b_eq[:6], b_eq[6:]
        self.A_hard, self.b_hard = A[:me], b[:me]
        self.Jc = Jc = A[:6 * nc]
        self.Jc_base_T, self.Jc_joints_T = Jc[:, :6].T, Jc[:, 6:].T
        self.M_base, self.M_joints = d.M[:6], d.M[6:]  # views of pinocchio's data, refreshed by each update
        self.nle_base, self.nle_joints = d.nle[:6], d.nle[6:]
        self.cones = B["cones"]
        self.cones[:] = [(None, None)] * nc
        self.C_blocks = [C[18 * i:18 * i + 18, nv + 6 * i:nv + 6 * i + 6] for i in range(nc)]
        self.u_blocks = [hi[18 * i:18 * i + 18] for i in range(nc)]
        self.k = k = 18 * nc
        self.C, self.l, self.u = C, lo, hi
        self.lb_joints, self.ub_joints = lb[6:nv], ub[6:nv]
        cones = (C[:k], lo[:k], hi[:k]) if nc else (None, None, None)
        self.problem = QPProblem._trusted(H, g, A_eq, b_eq, *cones, lb, ub)
        self.problem_torque = QPProblem._trusted(H, g, A_eq, b_eq, C, lo, hi, lb, ub)
        self.problem_relaxed = QPProblem._trusted(H, g, A_eq, b_eq, *cones)

    def torques(self, x: np.ndarray) -> np.ndarray:
        """tau = M_a dv + h_a - J_c,a^T w for a QP solution x."""
        nv = self.M_joints.shape[1]
        tau = self.M_joints @ x[:nv]
        tau += self.nle_joints
        if self.k:
            tau -= self.Jc_joints_T @ x[nv:]
        return tau


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
        # Each QP first tries the active set of its previous optimum, accepted only with a KKT certificate, and
        # otherwise goes to the backend solved cold (see ActiveSetGuessSolver): standing or walking, the active
        # set rarely changes from one tick to the next.
        self.solver = ActiveSetGuessSolver(make_solver(self.spec.solver))
        # compiled assembly and torques (wbcbench.qp._jit); False runs the numpy reference code, same answers
        self.jit = _jit.JIT_ENABLED
        self.relaxed_solver = ActiveSetGuessSolver(make_solver(self.spec.solver))
        self.torque_solver = ActiveSetGuessSolver(make_solver(self.spec.solver))
        lo, hi = robot.position_limits
        self.q_lo, self.q_hi = lo, hi
        self.v_max = robot.velocity_limit
        self.tau_max = robot.effort_limit
        self.fallback_pd = None
        self._sides = tuple(Side)
        self._buf: dict[tuple[int, int], dict] = {}
        self._stacks: dict[tuple[Side, ...], tuple[TaskStack, int]] = {}
        self._layouts: dict[tuple[Side, ...], _QPLayout] = {}
        self._t_pin = self._t_solve = 0.0
        self._limits_src: tuple = (None, None, None)
        self._tau_lim_src = None
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
        self.base_feedback = (BaseFeedback(robot, dt, self.spec.base_feedback)
                              if self.spec.base_feedback is not None and mode is not ActuationMode.TORQUE else None)

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
        if self.jit:
            self._warm_up(meas)

    def _warm_up(self, meas: Measurement) -> None:
        """Assemble and solve this tick's QP once, without acting: the compiled kernels are compiled (or loaded
        from their cache) here rather than in the first timed step. The counters and status are left as they
        were; the solver may keep the optimum's active set as its next guess (a guess is always certified)."""
        q, v = self._state(meas)
        update_kinematics(self.model, self.data, q, v)
        saved = (self.n_relaxed, self.n_fallback, self.qp_status)
        self._solve(q, v, tuple(s for s in self._sides if self.contacts[s].active))
        self.n_relaxed, self.n_fallback, self.qp_status = saved

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
        q, v = self._state(meas)
        t0 = perf_counter()
        update_kinematics(m, d, q, v)
        self._t_pin = perf_counter() - t0
        if self.base_feedback is not None:
            refs = self.base_feedback.correct(meas, refs, self.q_int)
        if self.stabilizer is not None:
            refs = self.stabilizer.correct(meas, refs, self.q_int)
        self._set_references(refs)
        self._update_contacts(meas.t, refs)
        contacts = self.contacts
        active = tuple(s for s in self._sides if contacts[s].active)
        solved = self._solve(q, v, active)
        if solved is None:
            return self._fallback(meas, list(active))
        x, tau = solved
        nv = self.nv
        self.dv = x[:nv]
        for i, s in enumerate(active):
            self.wrench[s] = x[nv + 6 * i: nv + 6 * i + 6]
        if len(active) < 2:
            for s in self._sides:
                if s not in active:
                    self.wrench[s][:] = 0.0
        self.tau = tau
        if self.mode is ActuationMode.TORQUE:
            return Command(tau=tau)
        self.v_int = self.v_int + self.dv * self.dt
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
            R = refs.feet_rotation.get(s)
            if R is None:
                R = sw.reference.rotation
            sw.set_reference(pin.SE3(R, np.asarray(p)), np.concatenate([vel, np.zeros(3)]),
                             np.concatenate([acc, np.zeros(3)]))

    def _task_stack(self, active: tuple[Side, ...]) -> tuple[TaskStack, int]:
        """The task stack for a set of active contacts (built once per set) and its number of constraint tasks.

        Rows: the active contacts' motion rows and the priority-0 tasks (equality constraints) first, then the
        weighted tasks of priority 1 and the swing tasks of the free feet (the cost), zero weights left out."""
        entry = self._stacks.get(active)
        if entry is None:
            hard = [self.contacts[s].contact for s in active] + [t for t in self.tasks if t.name in self.hard]
            soft = [t for t in self.tasks if t.name not in self.hard]
            soft += [self.swing[s] for s in self._sides if s not in active]
            entry = self._stacks[active] = (TaskStack(hard + soft, self.nv, skip_zero_weight=soft), len(hard))
        return entry

    def _buffers(self, nc: int, n_eq: int) -> dict:
        """Preallocated QP arrays for `nc` active contacts and `n_eq` equality rows (allocated once per shape).

        Constant parts are written here once: the wrench block of H (diagonal regularisation), the zero
        blocks of g and A_eq, the -inf lower bounds of the wrench cones, the infinite bounds of the base and
        the wrenches."""
        key = (nc, n_eq)
        buf = self._buf.get(key)
        if buf is None:
            nv, na = self.nv, self.robot.na
            n = nv + 6 * nc
            H = np.zeros((n, n))
            H.reshape(-1)[nv * (n + 1)::n + 1] = self.spec.regularization_wrench
            g = np.zeros(n)
            buf = {
                "H": H, "H_dv": H[:nv, :nv], "H_diag_dv": H.reshape(-1)[:nv * (n + 1):n + 1],
                "g": g, "g_dv": g[:nv],
                "A_eq": np.zeros((n_eq, n)), "b_eq": np.zeros(n_eq),
                "C": np.zeros((18 * nc + na, n)),
                "l": np.concatenate([np.full(18 * nc, -np.inf), np.zeros(na)]),
                "u": np.zeros(18 * nc + na),
                "lb": np.full(n, -np.inf), "ub": np.full(n, np.inf),
                "cones": [(None, None)] * nc,
            }
            self._buf[key] = buf
        return buf

    def _limit_rows(self) -> tuple[np.ndarray, ...]:
        """[q_hi; q_lo], [v_max; -v_max] (2, na) and two work rows; rebuilt when a limit attribute is replaced
        (tests and users assign new arrays to q_lo, q_hi, v_max)."""
        src = self._limits_src
        if src[0] is not self.q_hi or src[1] is not self.q_lo or src[2] is not self.v_max:
            na = self.robot.na
            self._limits = (np.stack([self.q_hi, self.q_lo]), np.stack([self.v_max, -self.v_max]),
                            np.empty((2, na)), np.empty((2, na)))
            self._limits_src = (self.q_hi, self.q_lo, self.v_max)
        return self._limits

    def _torque_limit(self) -> np.ndarray:
        """tau_max (1 + 1e-9), the accepted torques without the torque rows; rebuilt when tau_max is replaced."""
        if self._tau_lim_src is not self.tau_max:
            self._tau_lim, self._tau_lim_src = self.tau_max * (1 + 1e-9), self.tau_max
        return self._tau_lim

    def _solve(self, q: np.ndarray, v: np.ndarray, active: tuple[Side, ...]) -> tuple[np.ndarray, np.ndarray] | None:
        """Assemble and solve the QP; (x, tau) or None when even the relaxed QP fails."""
        m, d = self.model, self.data
        stack, n_hard = self._task_stack(active)
        A, b = stack.acceleration_rows(m, d)  # the same arrays (refilled) while the stack's layout holds
        L = self._layouts.get(active)
        if L is None or L.slices is not stack.slices:  # first time, or the stack's layout changed
            L = self._layouts[active] = _QPLayout(self, active, stack, n_hard, A, b)
        if self.jit:
            return self._solve_jit(q, v, active, L)
        # ---- cost: sqrt(w)-scaled rows of every weighted task, one product for the Hessian
        Aw = L.Aw
        np.multiply(L.A_cost, L.sw_column, out=Aw)
        np.multiply(L.b_cost, L.minus_sw, out=L.bw)
        np.matmul(Aw.T, Aw, out=L.H_dv)
        L.H_diag_dv += self.spec.regularization_dv
        np.matmul(Aw.T, L.bw, out=L.g_dv)
        # ---- equalities: floating-base dynamics, contact motion, hard tasks (stack rows: contacts first)
        L.A_eq_M[...] = L.M_base
        np.negative(L.Jc_base_T, out=L.A_eq_w)
        L.A_eq_J[...] = L.A_hard
        np.negative(L.nle_base, out=L.b_eq_h)
        L.b_eq_J[...] = L.b_hard
        # ---- inequalities: wrench cones (torque limits added lazily below); bounds: joint limits
        self._fill_cones(L, active)
        # a_hi = min(2 (q_hi - q - v h) / h^2, (v_max - v) / dt), a_lo likewise: both rows at once
        QL, VL, T, U = self._limit_rows()
        vj = v[6:]
        h = self.spec.joint_limit_horizon
        s_ = vj * h
        s_ += q[7:]
        np.subtract(QL, s_, out=T)
        T *= 2 / h**2
        np.subtract(VL, vj, out=U)
        U /= self.dt
        np.minimum(T[0], U[0], out=L.ub_joints)
        np.maximum(T[1], U[1], out=T[1])
        np.minimum(T[1], L.ub_joints, out=L.lb_joints)
        t0 = perf_counter()
        # Torque limits are lazy constraints: solve without them, and only if the optimum violates one solve
        # again with all of them (then the optimum is exactly the full problem's).
        res = self.solver.solve(L.problem)
        if res.ok:
            tau = L.torques(res.x)
            if (np.abs(tau) <= self._torque_limit()).all():
                self._t_solve = perf_counter() - t0
                self.qp_status = QP_OK
                return res.x, tau
        return self._solve_limited(L, res, t0)

    def _solve_jit(self, q: np.ndarray, v: np.ndarray, active: tuple[Side, ...],
                   L: _QPLayout) -> tuple[np.ndarray, np.ndarray] | None:
        """:meth:`_solve` after the rows, with the compiled assembly and torques (``_kernels``): the same QP,
        the same answers."""
        self._fill_cones(L, active)
        QL, VL, _, _ = self._limit_rows()
        P = L.problem
        _kernels.assemble(L.A_cost, L.b_cost, L.sw, self.spec.regularization_dv, L.H_dv, L.g_dv, L.M_base,
                          L.nle_base, L.Jc, L.A_hard, L.b_hard, P.A_eq, P.b_eq, q[7:], v[6:], QL, VL,
                          self.spec.joint_limit_horizon, self.dt, L.lb_joints, L.ub_joints)
        t0 = perf_counter()
        res = self.solver.solve(P)
        if res.ok:
            tau, within = _kernels.torques(L.M_joints, L.nle_joints, L.Jc, res.x, self._torque_limit())
            if within:
                self._t_solve = perf_counter() - t0
                self.qp_status = QP_OK
                return res.x, tau
        return self._solve_limited(L, res, t0)

    def _fill_cones(self, L: _QPLayout, active: tuple[Side, ...]) -> None:
        """Copy the active contacts' wrench-cone rows into the QP, only those a contact replaced (force ramps)."""
        cones = L.cones
        for i, s in enumerate(active):
            Cr, ur = self.contacts[s].contact.force_rows()
            C_prev, u_prev = cones[i]
            if Cr is not C_prev:
                L.C_blocks[i][...] = Cr
            if ur is not u_prev:
                L.u_blocks[i][...] = ur
            cones[i] = (Cr, ur)

    def _fill_torque_rows(self, L: _QPLayout) -> None:
        """Write the torque-limit rows ``-tau_max <= M_a dv + h_a - J_c,a^T w <= tau_max`` into ``L.problem_torque``."""
        nv, k, C, lo, hi = self.nv, L.k, L.C, L.l, L.u
        C[k:] = 0.0
        C[k:, :nv] = L.M_joints
        np.negative(L.Jc_joints_T, out=C[k:, nv:])
        lo[k:] = -self.tau_max - L.nle_joints
        hi[k:] = self.tau_max - L.nle_joints

    def _solve_limited(self, L: _QPLayout, res, t0: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The first solve failed or its torques exceed a limit: solve with the torque rows, then relaxed."""
        if res.ok:
            self._fill_torque_rows(L)
            res = self.torque_solver.solve(L.problem_torque)
        self._t_solve = perf_counter() - t0
        if res.ok:
            self.qp_status = QP_OK
            return res.x, L.torques(res.x)
        # relaxed: keep the contact rows, drop joint and torque limits
        self.n_relaxed += 1
        res = self.relaxed_solver.solve(L.problem_relaxed)
        if res.ok:
            self.qp_status = QP_RELAXED
            return res.x, L.torques(res.x)
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
