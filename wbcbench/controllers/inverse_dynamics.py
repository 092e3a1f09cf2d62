"""TSID-like inverse-dynamics controllers, paper 000 Sections 3.2-3.3: tsid-torque and tsid-position.

The QP (tasks, contacts with their force ramps, regularisation, limits) is `InverseDynamicsFormulation`
(id_formulation.py); a controller here holds only policy:

* which state the QP is written at: torque mode the measured state, every tick (tau = M_a dv + h_a - J_c,a^T w
  is sent); position mode the integrated state: dv is integrated twice on the manifold and the integrated
  (q, v) go to the joint servos (Section 3.3);
* the solve order: the QP without torque rows, and, only when its torques exceed a limit, with them (then the
  optimum is exactly the full problem's). If the QP fails it is solved again without the joint-limit and
  torque-limit rows (the robot's safety is better served by a slightly violated limit than by no command). If
  that fails too, the safe fallback is used: torque mode sends the joint-pd law (PD to the current posture plus
  gravity and contact compensation), position mode holds the last integrated posture with zero velocity. Both
  events are counted and logged per tick;
* the stabilizer of the task set (any `wbcbench.stabilizers` type), in front of the QP;
* servo feed-forward (task set `servo_feedforward:`, position and SPD modes): the QP's torques of the chosen joints
  handed to their servos, so that a servo delivers the model's torque without first lagging its set point by
  tau / kp. Position mode offsets the set point by tau / kp (kp: the profile's position gains; the servo's torque
  kp (q* + tau / kp - q) + kd (v* - v) is tau at zero tracking error, clipped at the effort limit as before); SPD
  mode sends tau as its feed-forward. Without it the stance hip roll servos of the generated humanoids sagged by
  their load over kp (GR2 T2 D: 0.013 rad, 95 N m at 6150 N m/rad), the real swing foot ran 5-9 mm below the
  model's and touched down 0.1 s early with 65 % of the weight, and the robot fell at the next lift-off.
  `all_but_ankles` leaves out the two joints nearest each sole: the model's ankle torques carry its contact
  wrench, whose CoP lies in the relaxed model sole (`contacts.model_sole`), not in the real one.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from time import perf_counter

import numpy as np
import pinocchio as pin

from ..jit import njit
from ..qp.active_set_guess import ActiveSetGuessSolver
from ..qp.registry import make_solver
from ..robots import Robot, Side
from ..stabilizers.base import Stabilizer
from ..tasks import Contact6D, FrameTask
from ..tasks.registry import build_task
from ..types import ActuationMode, Command, Measurement, ModelFeedback, References
from .base import Controller
from .id_formulation import InverseDynamicsFormulation
from .plan_corrections import PlanCorrections
from .task_references import TaskReferences
from .taskset import TaskSetSpec, load_taskset, taskset_path

_LEFT, _RIGHT = Side.LEFT, Side.RIGHT  # the enum's members looked up once (log values every tick)

QP_OK, QP_RELAXED, QP_FALLBACK = 0, 1, 2


def _servo_feedforward_gains(robot: Robot, which: str) -> np.ndarray | None:
    """(na,) per actuated joint 1 / kp (the profile's position gains) where the QP torque is fed forward through the
    set point (`which`: a `servo_feedforward` choice), 0 elsewhere; None for `none`."""
    if which == "none":
        return None
    kp, _ = robot.profile.position_gains.resolve(robot.joint_names, robot.profile.file)
    on = np.ones(robot.na)
    if which == "all_but_ankles":
        m = robot.model
        for s in Side:  # the two actuated joints nearest the sole on its chain from the root
            jid, left_out = m.frames[robot.sole_frame_id(s)].parentJoint, 0
            while jid > 0 and left_out < 2:
                if m.nvs[jid] == 1:
                    on[m.joints[jid].idx_v - 6] = 0.0
                    left_out += 1
                jid = m.parents[jid]
    return np.divide(on, kp, out=np.zeros(robot.na), where=kp > 0)


@njit(exact=True)
def _integrate_velocity(v, dv, dt, v_out, step_out):
    """``v_out = v + dv dt`` and ``step_out = v_out dt``, operation by operation as numpy's (no fused
    multiply-add)."""
    for i in range(v.shape[0]):
        vi = v[i] + dv[i] * dt
        v_out[i] = vi
        step_out[i] = vi * dt


def _integrated_velocity(v: np.ndarray, dv: np.ndarray, dt: float, step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The position schemes' model velocity after a tick, ``v + dv dt`` (a new array), and the configuration's
    step ``(v + dv dt) dt`` (into ``step``), in one compiled call (three numpy operations took 1.2 us)."""
    out = np.empty(v.shape[0])
    _integrate_velocity(v, dv, dt, out, step)
    return out, step


def _ankle_pitch_axes(robot: Robot) -> dict:
    """Per side, the ankle pitch joint (the joint above the sole's, its index) and its axis (3,) in its own frame."""
    m = robot.model
    d = m.createData()
    pin.computeJointJacobians(m, d, robot.q0)
    axes = {}
    for s in Side:
        j = m.parents[m.frames[robot.sole_frame_id(s)].parentJoint]
        local = pin.getJointJacobian(m, d, j, pin.ReferenceFrame.LOCAL)[3:, m.joints[j].idx_v]
        axes[s] = (j, local / np.linalg.norm(local))
    return axes


class InverseDynamicsController(Controller):
    """Inverse dynamics on `InverseDynamicsFormulation` with the policy of the module docstring.

    Args:
        robot, mode, dt: as every controller.
        taskset: the task set, or the path of its YAML file (default: `tasksets/<robot>/<name>.yaml`).
        stabilizer: a stabilizer to use instead of the task set's (None: the task set's, if any).
    """

    modes = (ActuationMode.TORQUE, ActuationMode.POSITION, ActuationMode.SPD)
    #: frame, contact and CoM tasks evaluated in one compiled call (`TaskStack(compiled_frames=...)`): the same
    #: rows as pinocchio's to rounding (tests/tasks/test_compiled_rows.py compares the commands), 7 us a tick less
    compiled_frames = True

    def __init__(self, robot: Robot, mode: ActuationMode, dt: float, taskset: TaskSetSpec | str | Path | None = None,
                 stabilizer: Stabilizer | None = None):
        super().__init__(robot, mode, dt)
        if taskset is None or isinstance(taskset, (str, Path)):
            taskset = load_taskset(taskset or taskset_path(robot, self.name), robot)
        self.spec = spec = taskset
        self._log_active = np.zeros(2)  # the contact_active log values (the caller copies them each tick)
        m = self.model = robot.model
        self.nv = m.nv
        tasks = [build_task(robot, t) for t in spec.tasks]
        hard = [t for t, ts in zip(tasks, spec.tasks) if ts.hard]
        soft = [t for t, ts in zip(tasks, spec.tasks) if not ts.hard]
        c = spec.contacts
        sole = robot.profile.sole
        length, width = c.model_sole or (sole.length, sole.width)
        metric = c.wrench_metric_matrix(length, width, sole.center)
        contacts = {s: Contact6D(m, robot.profile.feet[s].frame, length=length, width=width, center=sole.center,
                                 kp=c.kp, kd=c.kd, mu=c.mu, min_normal_force=c.min_normal_force,
                                 max_normal_force=c.max_normal_force, name=f"contact_{s.value}", drift=c.drift,
                                 error=c.error, wrench_metric=metric) for s in Side}
        sw = spec.swing_foot
        swing = {s: FrameTask(m, robot.profile.feet[s].frame, name=f"swing_{s.value}", weight=sw.weight, kp=sw.kp,
                              kd=sw.kd, mask=sw.mask) for s in Side}
        self.formulation = F = InverseDynamicsFormulation(
            m, soft, contacts, swing, hard_tasks=hard, position_limits=robot.position_limits,
            velocity_limit=robot.velocity_limit, effort_limit=robot.effort_limit,
            regularization_dv=spec.regularization_dv, regularization_wrench=spec.regularization_wrench,
            wrench_axis_weights=spec.regularization_wrench_axes,
            wrench_target_weight=spec.regularization_wrench_target, joint_limit_horizon=spec.joint_limit_horizon,
            transition_time=c.transition_time, dt=dt, compiled_frames=self.compiled_frames,
            unload_before_lift_off=c.unload_before_lift_off)
        self.data = F.data
        self.tasks = tasks
        self.task_by_name = F.task_by_name
        self.references = TaskReferences(tasks, swing, swing_pitch=spec.swing_pitch_with_leg)
        # Each QP first tries the active set of its previous optimum, accepted only with a KKT certificate, and
        # otherwise goes to the backend solved cold (see ActiveSetGuessSolver): standing or walking, the active
        # set rarely changes from one tick to the next.
        self.solver = ActiveSetGuessSolver(make_solver(spec.solver))
        self.relaxed_solver = ActiveSetGuessSolver(make_solver(spec.solver))
        self.torque_solver = ActiveSetGuessSolver(make_solver(spec.solver))
        self.fallback_pd = None
        self._t_pin = self._t_solve = 0.0
        self.n_relaxed = 0
        self.n_fallback = 0
        self.qp_status = QP_OK
        self.tau = np.zeros(robot.na)
        self.dv = np.zeros(self.nv)
        self._v_step = np.zeros(self.nv)  # the position schemes' configuration step of a tick (`step`)
        self.q_int = None
        self.v_int = None
        # the task set's correction stages (plan_corrections.py); those that need an integrated model only in
        # position and SPD modes (torque mode feeds back the measured state, and its contact forces press a landing
        # foot down)
        self.corrections = PlanCorrections(robot, dt, spec, stabilizer,
                                           integrated_model=mode is not ActuationMode.TORQUE)
        self._log_sources = self.corrections.log_sources
        # the ankle pitch joints' axes (a toe-off's swing turns about them, `_set_references`), for a task set that
        # takes the plan's swing pitch
        self._ankle_axes = _ankle_pitch_axes(robot) if spec.swing_pitch_with_leg else {}
        # position and SPD modes: the joints whose QP torque goes to their servos (module docstring)
        self._ff_over_kp = (None if mode is ActuationMode.TORQUE
                            else _servo_feedforward_gains(robot, spec.servo_feedforward))

    @property
    def stabilizer(self) -> Stabilizer | None:
        """The stabilizer in front of the solve (None: none), the task set's or the one given."""
        return self.corrections.stabilizer

    # ------------------------------------------------------------------ limits (the formulation's, replaceable)
    @property
    def wrench(self) -> dict:
        """Per side, the contact wrench (6,) of the last solve [N, N m], LOCAL sole frame (zero if inactive)."""
        return self.formulation.wrenches

    @property
    def contacts(self) -> dict:
        """Per side, the formulation's `ContactState` (contact task, active flag, force ramp)."""
        return self.formulation.contacts

    # ------------------------------------------------------------------ lifecycle
    def reset(self, meas: Measurement, refs: References) -> None:
        q, v = meas.q.copy(), meas.v.copy()
        self.q_int, self.v_int = q.copy(), np.zeros(self.nv) if self.mode is not ActuationMode.TORQUE else v
        F = self.formulation
        F.update(q, np.zeros(self.nv))
        F.reset_references(self.robot.q0, refs.contacts)
        from .joint_pd import JointPD
        self.fallback_pd = JointPD(self.robot, ActuationMode.TORQUE, self.dt)
        self._warm_up(meas)
        # the stabilizer's feedback at reset holds the warm-up solve's wrenches
        self.corrections.reset(meas, refs, lambda: self.feedback(at_reset=True), self._state(meas)[0])

    def _warm_up(self, meas: Measurement) -> None:
        """Assemble and solve this tick's QP once, without acting: the compiled kernels are compiled (or loaded
        from their cache) here rather than in the first timed step. The counters and status are left as they
        were; the solver may keep the optimum's active set as its next guess (a guess is always certified)."""
        q, v = self._state(meas)
        self.formulation.update(q, v)
        saved = (self.n_relaxed, self.n_fallback, self.qp_status)
        self._solve()
        self.n_relaxed, self.n_fallback, self.qp_status = saved

    def _state(self, meas: Measurement) -> tuple[np.ndarray, np.ndarray]:
        if self.mode is ActuationMode.TORQUE:
            return meas.q, meas.v
        return self.q_int, self.v_int

    def feedback(self, at_reset: bool = False) -> ModelFeedback:
        """What the stabilizer may know of the model: its configuration, active contacts, last wrenches and
        contact placements (at the last `update`); at reset also the contact and frame-task references."""
        if not at_reset:
            return self._stabilizer_feedback(None)
        F = self.formulation
        active = F.active
        contact_refs = {s: cs.contact.reference for s, cs in F.contacts.items() if cs.contact.reference is not None}
        task_refs = {t.name: t.reference for t in self.tasks if isinstance(t, FrameTask)}
        return ModelFeedback(self._model_q(), frozenset(active), F.wrenches, _ContactPlacements(F, active),
                             contact_refs, task_refs)

    _feedback_active: tuple = ((), frozenset())

    def _stabilizer_feedback(self, refs: References | None) -> ModelFeedback:
        """`feedback()` at a tick (the corrections' callable: `refs` unused), in one call."""
        F = self.formulation
        active = F.active
        held = self._feedback_active
        if held[0] != active:  # the contact set changes a few times a walk: its frozenset made then
            held = self._feedback_active = (active, frozenset(active))
        return ModelFeedback.of_tick(self._model_q(), held[1], F.wrenches, _ContactPlacements(F, active))

    def _model_q(self) -> np.ndarray:
        return self.q_int

    # ------------------------------------------------------------------ one tick
    def step(self, meas: Measurement, refs: References) -> Command:
        F = self.formulation
        q, v = self._state(meas)
        # the corrections on the model of the last solve (the stabilizer: its wrenches and contact placements)
        refs = self.corrections.apply(meas, refs, q, self._stabilizer_feedback)
        if self.mode is ActuationMode.TORQUE:
            q = self.corrections.configuration(q)
        t0 = perf_counter()
        F.update(q, v)
        self._t_pin = perf_counter() - t0
        self._set_references(refs)
        F.set_contacts(meas.t, refs.contacts, refs.lift_off)
        self._set_contact_pitch(refs)
        solved = self._solve()
        if solved is None:
            return self._fallback(meas, list(F.active))
        sol = F.accept(*solved)
        self.dv = sol.dv
        self.tau = sol.tau
        if self.mode is ActuationMode.TORQUE:
            return Command(tau=sol.tau)
        self.v_int, step = _integrated_velocity(self.v_int, self.dv, self.dt, self._v_step)
        self.q_int = pin.integrate(self.model, self.q_int, step)
        ff = self._ff_over_kp
        if ff is None:
            cmd = Command(q=self.q_int[7:].copy(), v=self.v_int[6:].copy())
        elif self.mode is ActuationMode.SPD:
            cmd = Command(tau=np.where(ff > 0.0, sol.tau, 0.0), q=self.q_int[7:].copy(), v=self.v_int[6:].copy())
        else:
            cmd = Command(q=self.q_int[7:] + ff * sol.tau, v=self.v_int[6:].copy())
        return self.corrections.command(cmd)

    def _set_references(self, refs: References) -> None:
        axes = None
        if self.references.swing_pitch and refs.swing_pitch:
            # a toe-off's swing (4 values) turns about the ankle pitch joint's axis as the encoders put it: the
            # ankle roll joint then stays where the flat foot has it (about the foot's own lateral axis, a foot
            # pitched by a radian under a shank leaning sideways turns the ankle roll by a few tenths)
            axes = {s: self._ankle_pitch_axis(s) for s in refs.feet if len(refs.swing_pitch.get(s, ())) > 3}
        self.references.apply(refs, axes)
        if refs.contact_poses:
            self.formulation.set_contact_references(refs.contact_poses)
        self.formulation.set_wrench_targets(self._wrench_targets(refs))

    def _ankle_pitch_axis(self, side: Side) -> np.ndarray:
        """The world axis (3,) of the ankle pitch joint (the joint above the sole's) at the last `update`."""
        j, local = self._ankle_axes[side]
        return self.formulation.data.oMi[j].rotation @ local

    def _set_contact_pitch(self, refs: References) -> None:
        """A foot still in contact with a pitch offered about a sole edge (a toe-off before its lift-off): its
        contact turns about that edge (`InverseDynamicsFormulation.set_contact_pitch`)."""
        F = self.formulation
        roll = None
        if self.references.swing_pitch and refs.swing_pitch:
            roll = {s: d for s, d in refs.swing_pitch.items() if len(d) > 3 and d[3] != 0.0 and s not in refs.feet}
        if roll or F.on_edge:
            F.set_contact_pitch(roll or {})

    def _wrench_targets(self, refs: References) -> dict | None:
        """The wrench targets of this tick (policy hook): the references'."""
        return refs.wrench_targets

    def _solve(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Assemble and solve the QP; (x, tau) or None when even the relaxed QP fails."""
        F = self.formulation
        P = F.problem()
        t0 = perf_counter()
        # Torque limits are lazy constraints: solve without them, and only if the optimum violates one solve
        # again with all of them (then the optimum is exactly the full problem's).
        res = self._first_solve(P)
        if res.ok:
            tau, within = F.torques(res.x)
            if within:
                self._t_solve = perf_counter() - t0
                self.qp_status = QP_OK
                return res.x, tau
        return self._solve_limited(res, t0)

    def _first_solve(self, P):
        """The tick's first solve, without the torque rows (a hook: a controller may bound it further)."""
        return self.solve_qp(self.solver, P)

    def _solve_limited(self, res, t0: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The first solve failed or its torques exceed a limit: solve with the torque rows, then relaxed."""
        F = self.formulation
        if res.ok:
            res = self.solve_qp(self.torque_solver, F.problem_with_torque_limits())
        self._t_solve = perf_counter() - t0
        if res.ok:
            self.qp_status = QP_OK
            return res.x, F.torques(res.x)[0]
        # relaxed: keep the contact rows, drop joint and torque limits
        self.n_relaxed += 1
        res = self.solve_qp(self.relaxed_solver, F.problem_relaxed())
        if res.ok:
            self.qp_status = QP_RELAXED
            return res.x, F.torques(res.x)[0]
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
        ch = {"qp_status": [], "tau_cmd": self.robot.joint_names}
        ch.update(self.corrections.log_channels())  # the stabilizer's and any other logging stage's
        ch.update({"wrench_qp_left": w, "wrench_qp_right": w, "contact_active": ["left", "right"]})
        return ch

    def log_values(self) -> list:
        F = self.formulation
        active, contacts, wrenches = self._log_active, F.contacts, F.wrenches
        active[0], active[1] = contacts[_LEFT].active, contacts[_RIGHT].active
        logs = self._log_sources
        if len(logs) == 1:  # the usual: the stabilizer
            return [self.qp_status, self.tau, logs[0].log, wrenches[_LEFT], wrenches[_RIGHT], active]
        if not logs:
            return [self.qp_status, self.tau, wrenches[_LEFT], wrenches[_RIGHT], active]
        return [self.qp_status, self.tau, *[src.log for src in logs], wrenches[_LEFT], wrenches[_RIGHT], active]

    def status(self) -> dict:
        return self.corrections.status({"qp_relaxed_ticks": self.n_relaxed, "qp_fallback_ticks": self.n_fallback})


class _ContactPlacements(Mapping):
    """The world placements of the active contacts' frames at the formulation's last `update` (`ModelFeedback`'s
    `contact_poses`), computed when first read: a stabilizer that reads only the model's configuration (the DCM
    stabilizers) costs no frame update. Read it in the tick it is given (the next `update` moves the frames)."""

    __slots__ = ("_formulation", "_names", "_poses")

    def __init__(self, formulation, names) -> None:
        self._formulation, self._names, self._poses = formulation, names, None

    def _all(self) -> dict:
        if self._poses is None:
            F = self._formulation
            self._poses = {s: F.contact_placement(s) for s in self._names}
        return self._poses

    def __getitem__(self, key):
        return self._all()[key]

    def __iter__(self):
        return iter(self._all())

    def __len__(self) -> int:
        return len(self._names)

    def __repr__(self) -> str:
        return repr(self._all())


class TSIDTorque(InverseDynamicsController):
    name = "tsid-torque"
    default_mode = ActuationMode.TORQUE


class TSIDPosition(InverseDynamicsController):
    name = "tsid-position"
    default_mode = ActuationMode.POSITION
    modes = (ActuationMode.POSITION, ActuationMode.SPD)
