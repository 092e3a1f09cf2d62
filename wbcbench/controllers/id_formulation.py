"""The inverse-dynamics formulation: tasks and contacts -> one weighted QP -> accelerations, wrenches, torques.

TSID's split (robot, tasks, contacts, formulation, solver), in our style. Decision variables
x = [dv (nv); w_1 (6); ...; w_k (6)]: joint accelerations and one wrench per active contact (LOCAL contact frame,
at its origin, exerted by the ground on the robot)::

    min   sum_i w_i || A_i dv - b_i ||^2 + r_dv ||dv||^2 + r_w sum_c ||a * w_c||^2 + w_f sum_c ||w_c - w_c*||^2
    s.t.  M_b dv + h_b = J_c,b^T w                    floating-base rows of the dynamics (6)
          J_c dv = -J_c_dot v + Kp e_c - Kd J_c v     rigid contacts (6 per active contact)
          A_j dv = b_j                                hard tasks (equality constraints)
          C w <= u                                    friction pyramid, CoP in the sole, f_min <= f_z <= f_max
          A_r dv <= u_r                               barrier rows of the soft tasks that have them (self-collision)
          a_min <= dv_joints <= a_max                 joint position and velocity limits as acceleration bounds
          -tau_max <= M_a dv + h_a - J_c,a^T w <= tau_max   torque limits (a separate problem, see below)

with tau = M_a dv + h_a - J_c,a^T w. `a` (6,) weighs the wrench's axes in its regularisation (`wrench_axis_weights`,
default all 1); TSID's Contact6d uses a = (1, 1, 1e-3, 2, 2, 2): a moment about the sole costs 4e6 times as much as
the same number of newtons of normal force, so in double support the QP moves the CoP between the feet by shifting
normal force from one foot to the other rather than by ankle torques. A contact given its own metric
(`Contact6D`'s `wrench_metric` W, (6, 6) symmetric PSD) has ``w_c^T W w_c`` instead of ``r_w ||a * w_c||^2``
(`tsid_wrench_metric`: C++ TSID's, whose corner forces add their own regularisation). `w_c*` are wrench targets
(`References.wrench_targets`), weighted by `wrench_target_weight` (0: none).

The formulation owns the tasks, the contacts with their force ramps (a leaving contact's maximum normal force goes
to zero over `transition_time` before it is removed; an arriving one ramps in), the free-motion task of each
contact's link while it is not in contact (a swing foot), the regularisation and the limits. A leaving contact's
ramp starts when the contact is no longer wanted, or, with `unload_before_lift_off` and the planned lift-off times
given to `set_contacts`, `transition_time` before its planned lift-off, so that its load is zero when the foot
leaves (TSID's removeRigidContact unloads the contact before removing it). Per tick::

    F.update(q, v)                    # kinematics and dynamics of the state the QP is written at
    F.set_contacts(t, wanted, lift_off)   # the contact schedule (ramps), with the planned lift-offs ahead
    P = F.problem()                   # the QP, assembled in place (torque limits not included)
    tau, ok = F.torques(x)            # the torques of a solution, and whether they are within the limits
    P = F.problem_with_torque_limits()   /   F.problem_relaxed()   (no joint or torque limits)
    sol = F.accept(x)                 # accelerations, wrenches and torques of the solution kept

`acceleration_caps` (None by default) scales named frame tasks' commanded accelerations down while their position
error is large and their reference moves, and their angular ones while their rotation error is large
(tsid-teleop's out-of-reach caps: `_kernels.cap_task_accelerations`, one compiled call a tick).

Solving, and what to do when a solve fails, is the controller's policy. The problems' arrays are reused tick
after tick (refilled in place): a `QPProblem` from here is valid until the next call that assembles.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..qp.problem import QPProblem
from ..side import Side
from ..tasks import Contact6D, FrameTask, Task, TaskStack, update_kinematics
from . import _kernels

__all__ = ["ContactState", "IDSolution", "InverseDynamicsFormulation"]

_DIAG6 = np.diag_indices(6)


class ContactState:
    """A contact and its force ramp (the maximum normal force goes to 0 before the contact is removed)."""

    def __init__(self, contact: Contact6D):
        self.contact = contact
        self.active = True
        self.ramp_from = contact.nominal_max_normal_force
        self.ramp_to = contact.nominal_max_normal_force
        self.ramp_t0 = 0.0
        self.ramp_T = 0.0
        self.anchor = None  # the flat reference (R, p) a contact turning about a sole edge turns from

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


@dataclass(frozen=True, slots=True)
class IDSolution:
    """A solution of the formulation's QP: dv (nv,) [m/s^2, rad/s^2], the active contacts' wrenches (6,) each
    [N, N m] (LOCAL contact frame), tau (na,) [N m] the joint torques of the dynamics."""

    dv: np.ndarray
    wrenches: dict
    tau: np.ndarray


class _Layout:
    """Named views of the QP buffers and of the task stack's rows for one set of active contacts and one stack
    layout, made once, so that a tick only computes. The QPProblem objects are built once too: their arrays are
    refilled in place."""

    __slots__ = ("slices", "k", "kb", "barriers", "cap_rows", "A_cost", "b_cost", "sw", "Jc", "H_dv", "g_dv",
                 "H_diag_w", "g_w", "A_hard", "b_hard", "M_base", "M_joints", "nle_base", "nle_joints", "cones",
                 "C_blocks", "u_blocks", "C", "l", "u", "lb_joints", "ub_joints", "problem", "problem_torque",
                 "problem_relaxed", "targets_set", "rows", "buffers", "metric_blocks")

    def __init__(self, F: InverseDynamicsFormulation, active: tuple, stack: TaskStack, n_hard: int, A: np.ndarray,
                 b: np.ndarray):
        nv, na, d = F.nv, F.na, F.data
        nc = len(active)
        self.slices = stack.slices
        me = self.slices[n_hard - 1].stop if n_hard else 0
        n, n_eq = nv + 6 * nc, 6 + me
        # barrier rows (a soft task's rows, also as upper-bounded inequalities): (task, its rows in A, its rows in C)
        self.barriers, nb = [], 0
        for task, rows in zip(stack.tasks, stack.slices):
            if getattr(task, "barrier", None) is not None and any(task is t for t in F.tasks):
                self.barriers.append((task, rows, slice(18 * nc + nb, 18 * nc + nb + (rows.stop - rows.start))))
                nb += rows.stop - rows.start
        # the stack rows (x y z roll pitch yaw, -1: not selected) of the tasks with out-of-reach caps
        caps = F.acceleration_caps
        cap_rows = []
        if caps is not None:
            for task, rows in zip(stack.tasks, stack.slices):
                if task.name in caps[0]:
                    r = np.full(6, -1, dtype=np.int64)
                    r[np.asarray(task.rows)] = np.arange(rows.start, rows.stop)
                    cap_rows.append(r)
        self.cap_rows = np.array(cap_rows, dtype=np.int64).reshape(-1, 6)
        H = np.zeros((n, n))
        diag = H.reshape(-1)[::n + 1]
        diag[nv:] = np.tile(F.wrench_regularization_diagonal, nc)
        # the wrench blocks of the contacts with their own metric, and the metric
        self.metric_blocks = [(H[nv + 6 * i:nv + 6 * i + 6, nv + 6 * i:nv + 6 * i + 6], W) for i, W in enumerate(
            F.contacts[name].contact.wrench_metric for name in active) if W is not None]
        for block, W in self.metric_blocks:
            block[...] = W
        g = np.zeros(n)
        A_eq, b_eq = np.zeros((n_eq, n)), np.zeros(n_eq)
        C = np.zeros((18 * nc + nb + na, n))
        lo = np.concatenate([np.full(18 * nc + nb, -np.inf), np.zeros(na)])
        hi = np.zeros(18 * nc + nb + na)
        lb, ub = np.full(n, -np.inf), np.full(n, np.inf)
        self.H_dv, self.g_dv = H[:nv, :nv], g[:nv]
        self.H_diag_w, self.g_w = diag[nv:], g[nv:]
        self.targets_set = False
        self.A_cost, self.b_cost, self.sw = A[me:], b[me:], stack.sqrt_weights[me:]
        self.A_hard, self.b_hard = A[:me], b[:me]
        self.Jc = A[:6 * nc]
        self.M_base, self.M_joints = d.M[:6], d.M[6:]  # views of pinocchio's data, refreshed by each update
        self.nle_base, self.nle_joints = d.nle[:6], d.nle[6:]
        self.cones = [(None, None)] * nc
        self.C_blocks = [C[18 * i:18 * i + 18, nv + 6 * i:nv + 6 * i + 6] for i in range(nc)]
        self.u_blocks = [hi[18 * i:18 * i + 18] for i in range(nc)]
        self.k = 18 * nc
        self.kb = kb = 18 * nc + nb  # the cones, then the barrier rows; the torque rows after them
        self.C, self.l, self.u = C, lo, hi
        self.lb_joints, self.ub_joints = lb[6:nv], ub[6:nv]
        cones = (C[:kb], lo[:kb], hi[:kb]) if kb else (None, None, None)
        self.problem = QPProblem._trusted(H, g, A_eq, b_eq, *cones, lb, ub)
        self.problem_torque = QPProblem._trusted(H, g, A_eq, b_eq, C, lo, hi, lb, ub)
        self.problem_relaxed = QPProblem._trusted(H, g, A_eq, b_eq, *cones)
        self.rows = _kernels.AssemblyRows(self.A_cost, self.b_cost, self.sw, self.Jc, self.A_hard, self.b_hard,
                                          self.M_base, self.nle_base)
        self.buffers = _kernels.QPBuffers(self.H_dv, self.g_dv, A_eq, b_eq, self.lb_joints, self.ub_joints)


class InverseDynamicsFormulation:
    """Tasks + contacts -> the weighted inverse-dynamics QP (module docstring).

    Args:
        model: the robot's pinocchio model (a free-flyer base); the formulation keeps its own data.
        tasks: the weighted (soft) tasks, in the cost with their weights.
        contacts: one `Contact6D` per contact name (e.g. per `Side`), all active at first.
        free_tasks: per contact name, the task that moves the contact's link while the contact is inactive
            (e.g. a swing-foot `FrameTask`); in the cost only then.
        hard_tasks: tasks kept as equality constraints (after the contacts' rows).
        position_limits: (q_lo, q_hi) (na,) [rad]; velocity_limit, effort_limit: (na,) [rad/s], [N m].
        regularization_dv, regularization_wrench: weights of ||dv||^2 and ||a * w||^2.
        wrench_axis_weights: a (6,), >= 0, per axis of a contact wrench (fx fy fz tx ty tz) in its
            regularisation (None: all 1).
        wrench_target_weight: w_f of ||w_c - w_c*||^2 [1/N^2], applied on ticks with wrench targets.
        joint_limit_horizon: [s] horizon turning joint position limits into acceleration bounds.
        transition_time: [s] of a contact's force ramp.
        unload_before_lift_off: end a leaving contact's ramp at its planned lift-off (`set_contacts`' lift_off)
            rather than start it there.
        dt: the control period [s] (velocity limits as acceleration bounds).
        compiled_frames: evaluate the frame tasks in one compiled call (`TaskStack`'s option of that name: the
            same rows to rounding, not the same bits).
    The limit arrays (`q_lo`, `q_hi`, `v_max`, `tau_max`) may be replaced by new arrays at any time.
    """

    def __init__(self, model: pin.Model, tasks: Sequence[Task], contacts: Mapping, free_tasks: Mapping,
                 *, hard_tasks: Sequence[Task] = (), position_limits: tuple[np.ndarray, np.ndarray],
                 velocity_limit: np.ndarray, effort_limit: np.ndarray, regularization_dv: float = 1e-6,
                 regularization_wrench: float = 1e-5, wrench_axis_weights: Sequence[float] | None = None,
                 wrench_target_weight: float = 0.0, joint_limit_horizon: float = 0.01, transition_time: float = 0.05,
                 dt: float = 1e-3, compiled_frames: bool = False, unload_before_lift_off: bool = False):
        self.model = model
        self.compiled_frames = compiled_frames
        self.data = model.createData()
        self.nv = model.nv
        self.na = model.nv - 6
        self.tasks = list(tasks)
        self.hard_tasks = list(hard_tasks)
        self.task_by_name = {t.name: t for t in (*self.hard_tasks, *self.tasks)}
        self.contacts = {name: ContactState(c) for name, c in contacts.items()}
        self.free_tasks = dict(free_tasks)
        self.names = tuple(self.contacts)
        self.q_lo, self.q_hi = position_limits
        self.v_max, self.tau_max = velocity_limit, effort_limit
        self.regularization_dv = regularization_dv
        self.regularization_wrench = regularization_wrench
        a = np.ones(6) if wrench_axis_weights is None else np.asarray(wrench_axis_weights, dtype=float)
        if a.shape != (6,) or not np.all(np.isfinite(a)) or np.any(a < 0):
            raise ValueError(f"wrench_axis_weights must be 6 finite values >= 0, got {wrench_axis_weights!r}")
        self.wrench_regularization_diagonal = regularization_wrench * a**2
        self.wrench_target_weight = wrench_target_weight
        self.joint_limit_horizon = joint_limit_horizon
        #: whether an active contact was left on a sole edge by the last `set_contact_pitch` (a toe-off under way)
        self.on_edge = False
        #: None, or (task names, params [e0, e1, a_lin, a_ang, v0, v1, r0, r1, p0, p1]): the named frame tasks'
        #: commanded accelerations capped while their position error exceeds e0 and their reference moves faster
        #: than v0, the angular ones also while their rotation error exceeds r0 and the position error is under p0
        #: (`_kernels.cap_task_accelerations`;
        #: `set_acceleration_caps`). `n_capped_ticks` counts the ticks with a task capped
        self.acceleration_caps: tuple | None = None
        self.n_capped_ticks = 0
        self.transition_time = transition_time
        self.unload_before_lift_off = unload_before_lift_off
        self.dt = dt
        self.wrenches = {name: np.zeros(6) for name in self.names}
        self.active: tuple = self.names
        self._q = self._v = None
        self._targets = None
        self._stacks: dict[tuple, tuple[TaskStack, int]] = {}
        self._layouts: dict[tuple, _Layout] = {}
        self._layout: _Layout | None = None
        self._limits_src: tuple = (None, None, None)
        self._tau_lim_src = None

    # ------------------------------------------------------------------ state
    def update(self, q: np.ndarray, v: np.ndarray) -> None:
        """Kinematics and dynamics (mass matrix, nonlinear effects, Jacobians) at the state (q, v)."""
        update_kinematics(self.model, self.data, q, v)
        self._q, self._v = q, v

    def reset_references(self, q_reference: np.ndarray, active: Collection) -> None:
        """At rest (after `update`): every task's reference to its rest value, every contact's and free task's
        reference to where its frame is, the contacts in `active` on with their full force."""
        m, d = self.model, self.data
        for t in (*self.hard_tasks, *self.tasks):
            t.reset_reference(m, d, q_reference)
        for name, cs in self.contacts.items():
            cs.contact.set_edge(None)  # on the whole sole (a toe-off of a previous run ended)
            cs.anchor = None
            cs.contact.set_reference_to_current(m, d)
            cs.active = name in active
            f = cs.contact.nominal_max_normal_force
            cs.start_ramp(0.0, f, f, 0.0)
        for t in self.free_tasks.values():
            t.set_reference_to_current(m, d)
        self.active = tuple(n for n in self.names if self.contacts[n].active)
        self.on_edge = False

    def set_contacts(self, t: float, wanted: Collection, lift_off: Mapping | None = None) -> tuple:
        """The contact schedule at time t [s]: a contact no longer wanted ramps its maximum force from its
        current load to zero and is removed at the end of the ramp (its free task then starts where the frame
        is); a wanted one is made (reference: where the frame is now) and ramped in. Returns the active ones.

        lift_off: per wanted contact, the time [s] of its next planned lift-off (`References.lift_off`). With
        `unload_before_lift_off`, a contact whose lift-off is at most `transition_time` ahead is leaving: its
        ramp to zero starts now and ends at the lift-off, and it stays (unloaded) until it is no longer wanted.
        A leaving contact whose lift-off moves further ahead (a re-plan) ramps back in."""
        m, d = self.model, self.data
        T = self.transition_time
        ahead = lift_off if self.unload_before_lift_off and lift_off else None
        for name, cs in self.contacts.items():
            want = name in wanted
            t_off = ahead.get(name) if ahead is not None and want else None
            leaving = t_off is not None and t_off - t <= T
            if cs.active and (not want or leaving) and cs.ramp_to != 0.0:
                f_now = max(self.wrenches[name][2], 0.0)
                cs.start_ramp(t, min(f_now, cs.contact.nominal_max_normal_force), 0.0, t_off - t if leaving else T)
            elif want and not leaving and (not cs.active or cs.ramp_to == 0.0):
                if not cs.active:
                    cs.contact.set_edge(None)
                    cs.anchor = None
                    cs.contact.set_reference_to_current(m, d)
                cs.active = True
                cs.start_ramp(t, cs.contact.max_normal_force if cs.ramp_to == 0.0 else 0.0,
                              cs.contact.nominal_max_normal_force, T)
            if cs.active and cs.update(t) and not want:
                cs.active = False
                self.free_tasks[name].set_reference_to_current(m, d)
        self.active = tuple(n for n in self.names if self.contacts[n].active)
        return self.active

    def set_contact_references(self, poses: Mapping) -> None:
        """Replace the reference pose (SE3) of the given contacts that are active."""
        for name, pose in poses.items():
            cs = self.contacts[name]
            if cs.active:
                cs.contact.set_reference(pose)

    def set_contact_pitch(self, pitch: Mapping) -> None:
        """Active contacts turning about a sole edge (a toe-off): per contact name, (delta, rate, acc, pivot_x)
        [rad, rad/s, rad/s^2, m], the sole's pitch about its lateral axis through the edge at x = pivot_x in the
        contact frame (front edge: the toe, delta > 0 lifts the heel). The contact's wrench rows become the edge's
        (`Contact6D.set_edge`) and its reference the flat reference it had when the turn began, turned about the
        edge by delta, with the twist and its derivative of that turn; an active contact on an edge that is not in
        `pitch` goes back to its whole sole and its flat reference."""
        for name, cs in self.contacts.items():
            c = cs.contact
            d = pitch.get(name) if cs.active else None
            if d is None:
                if c.edge is not None and cs.active:
                    c.set_edge(None)
                    if cs.anchor is not None:
                        c.set_reference(pin.SE3(*cs.anchor))
                    cs.anchor = None
                continue
            delta, rate, acc, x = (float(v) for v in d)
            edge = "toe" if x > 0.0 else "heel"
            if c.edge != edge:
                if cs.anchor is None:
                    ref = c.reference
                    cs.anchor = (ref.rotation.copy(), ref.translation.copy())
                c.set_edge(edge)
            R0, p0 = cs.anchor
            cd, sd = np.cos(delta), np.sin(delta)
            Ry = np.array([[cd, 0.0, sd], [0.0, 1.0, 0.0], [-sd, 0.0, cd]])
            pe = np.array([x, 0.0, 0.0])
            c.set_reference(pin.SE3(R0 @ Ry, p0 + R0 @ (pe - Ry @ pe)),
                            np.array([0.0, 0.0, rate * x, 0.0, rate, 0.0]),
                            np.array([0.0, 0.0, acc * x, 0.0, acc, 0.0]))
        self.on_edge = any(cs.active and cs.contact.edge is not None for cs in self.contacts.values())

    def set_acceleration_caps(self, names: Collection[str], params: np.ndarray) -> None:
        """Cap the named frame tasks' commanded accelerations (`acceleration_caps`; params [e0, e1, a_lin, a_ang, v0,
        v1, r0, r1, p0, p1], r0 = r1 = inf: no angular trigger); the problems' layouts are made again with the tasks'
        rows."""
        params = np.asarray(params, dtype=float)
        if params.shape != (10,):  # the compiled kernel reads all ten
            raise ValueError(f"acceleration caps take 10 params [e0, e1, a_lin, a_ang, v0, v1, r0, r1, p0, p1], got "
                             f"shape {params.shape}")
        self.acceleration_caps = (tuple(names), params)
        self._layouts.clear()

    def set_wrench_targets(self, targets: Mapping | None) -> None:
        """The targets w_c* (6,) of this tick's wrench regularisation, by contact (None or empty: none)."""
        self._targets = targets or None

    def contact_placement(self, name) -> pin.SE3:
        """The world placement of a contact's frame at the last `update`."""
        return pin.updateFramePlacement(self.model, self.data, self.contacts[name].contact.frame_id)

    # ------------------------------------------------------------------ the QP
    def _task_stack(self, active: tuple) -> tuple[TaskStack, int]:
        """The task stack for a set of active contacts (built once per set) and its number of constraint tasks.

        Rows: the active contacts' motion rows and the hard tasks (equality constraints) first, then the weighted
        tasks and the free tasks of the inactive contacts (the cost), zero weights left out."""
        entry = self._stacks.get(active)
        if entry is None:
            hard = [self.contacts[n].contact for n in active] + self.hard_tasks
            soft = self.tasks + [self.free_tasks[n] for n in self.names if n not in active]
            entry = self._stacks[active] = (TaskStack(hard + soft, self.nv, skip_zero_weight=soft,
                                                        compiled_frames=self.compiled_frames), len(hard))
        return entry

    def _limit_rows(self) -> _kernels.JointLimits:
        """[q_hi; q_lo], [v_max; -v_max] (2, na), horizon and period; rebuilt when a limit attribute is replaced."""
        src = self._limits_src
        if src[0] is not self.q_hi or src[1] is not self.q_lo or src[2] is not self.v_max:
            self._limits = _kernels.JointLimits(np.stack([self.q_hi, self.q_lo]), np.stack([self.v_max, -self.v_max]),
                                                float(self.joint_limit_horizon), float(self.dt))
            self._limits_src = (self.q_hi, self.q_lo, self.v_max)
        return self._limits

    def _torque_limit(self) -> np.ndarray:
        """tau_max (1 + 1e-9), the accepted torques without the torque rows; rebuilt when tau_max is replaced."""
        if self._tau_lim_src is not self.tau_max:
            self._tau_lim, self._tau_lim_src = self.tau_max * (1 + 1e-9), self.tau_max
        return self._tau_lim

    def problem(self) -> QPProblem:
        """Assemble this tick's QP (without the torque-limit rows) for the active contacts."""
        active = self.active
        stack, n_hard = self._task_stack(active)
        A, b = stack.acceleration_rows(self.model, self.data)  # the same arrays (refilled) while the layout holds
        L = self._layouts.get(active)
        if L is None or L.slices is not stack.slices:  # first time, or the stack's layout changed
            L = self._layouts[active] = _Layout(self, active, stack, n_hard, A, b)
        self._layout = L
        if L.cap_rows.shape[0]:
            self.n_capped_ticks += _kernels.cap_task_accelerations(stack._b, stack._drift, stack._e, stack._v_ref,
                                                                   L.cap_rows, self.acceleration_caps[1]) > 0
        # wrench cones: copy the rows a contact replaced (force ramps)
        cones = L.cones
        for i, name in enumerate(active):
            Cr, ur = self.contacts[name].contact.force_rows()
            C_prev, u_prev = cones[i]
            if Cr is not C_prev:
                L.C_blocks[i][...] = Cr
            if ur is not u_prev:
                L.u_blocks[i][...] = ur
            cones[i] = (Cr, ur)
        self._fill_wrench_targets(L, active)
        _kernels.assemble(L.rows, self.regularization_dv, self._q[7:], self._v[6:], self._limit_rows(), L.buffers)
        nv = self.nv
        for task, rows, crows in L.barriers:
            task.barrier_rows(self.model, self.data, A[rows], b[rows], self._v, L.C[crows, :nv], L.u[crows])
        return L.problem

    def _fill_wrench_targets(self, L: _Layout, active: tuple) -> None:
        """The wrench block of the cost: r_w a^2 (or a contact's metric) + w_f on the diagonal and -w_f w* in g on
        ticks with targets."""
        targets, w = self._targets, self.wrench_target_weight
        if targets is not None and w > 0.0:
            L.H_diag_w.reshape(-1, 6)[...] = self.wrench_regularization_diagonal + w
            for block, W in L.metric_blocks:
                block[...] = W
                block[_DIAG6] += w
            for i, name in enumerate(active):
                np.multiply(targets[name], -w, out=L.g_w[6 * i:6 * i + 6])
            L.targets_set = True
        elif L.targets_set:
            L.H_diag_w.reshape(-1, 6)[...] = self.wrench_regularization_diagonal
            for block, W in L.metric_blocks:
                block[...] = W
            L.g_w[...] = 0.0
            L.targets_set = False

    def torques(self, x: np.ndarray) -> tuple[np.ndarray, bool]:
        """tau = M_a dv + h_a - J_c,a^T w (na,) [N m] of a solution x of the last assembled QP, and whether
        |tau| <= tau_max everywhere."""
        L = self._layout
        return _kernels.torques(L.M_joints, L.nle_joints, L.Jc, x, self._torque_limit())

    def problem_with_torque_limits(self) -> QPProblem:
        """The last assembled QP with the torque-limit rows ``-tau_max <= M_a dv + h_a - J_c,a^T w <= tau_max``."""
        L = self._layout
        nv, k, C = self.nv, L.kb, L.C
        C[k:] = 0.0
        C[k:, :nv] = L.M_joints
        np.negative(L.Jc[:, 6:].T, out=C[k:, nv:])
        L.l[k:] = -self.tau_max - L.nle_joints
        L.u[k:] = self.tau_max - L.nle_joints
        return L.problem_torque

    def problem_relaxed(self) -> QPProblem:
        """The last assembled QP without the joint-limit bounds (contact rows and cones kept)."""
        return self._layout.problem_relaxed

    def accept(self, x: np.ndarray, tau: np.ndarray) -> IDSolution:
        """Keep a solution of the last assembled QP: its wrenches become the contacts' current loads (zero for
        the inactive contacts)."""
        nv = self.nv
        active = self.active
        wrenches = self.wrenches
        for i, name in enumerate(active):
            wrenches[name] = x[nv + 6 * i: nv + 6 * i + 6]
        if len(active) < len(self.names):
            for name in self.names:
                if name not in active:
                    wrenches[name][:] = 0.0
        return IDSolution(x[:nv], {n: wrenches[n] for n in active}, tau)
