"""Concrete scenario kinds. Each is registered under its `kind` string."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import ConfigError, PlanningError, UnknownNameError
from ..recorder import channel
from ..robots import Side
from ..types import GRAVITY, JointReference, PointReference, PoseReference, References
from .base import Scenario


class SwayScenario(Scenario):
    """Stand on both feet while the CoM follows a sinusoid about its initial position.

    params: amplitude [m] (per axis x y z), frequency [Hz]. The reference starts at zero velocity by
    ramping the amplitude in over `ramp` seconds (default 0: the pure sinusoid, as the paper's test).
    """

    kind = "sway"

    def parse(self, params):
        self.amplitude = params.vector("amplitude", [0.0, 0.05, 0.0], length=3)
        self.frequency = params.float("frequency", 0.5, positive=True)
        self.settle = params.float("skip_for_error", 0.0, min=0.0)

    def setup(self, q0, com0):
        import pinocchio as pin
        super().setup(q0, com0)
        data = self.robot.model.createData()
        pin.framesForwardKinematics(self.robot.model, data, q0)
        self.ground = min(data.oMf[self.robot.sole_frame_id(s)].translation[2] for s in Side)

    def references(self, t: float) -> References:
        w = 2 * np.pi * self.frequency
        s, c = np.sin(w * t), np.cos(w * t)
        a = self.amplitude
        com, acc = self.com0 + a * s, -a * w * w * s
        # the ZMP of this CoM motion on the cart-table model: p = c - (c_z / g) c_ddot
        zmp = np.array([*(com[:2] - (com[2] - self.ground) / GRAVITY * acc[:2]), self.ground])
        return References(t=t, contacts=frozenset(Side), com=PointReference(com, a * w * c, acc), zmp=zmp)

    def metrics(self, log):
        com = channel(log, "com")
        ref = channel(log, "com_ref")
        t = log["t"]
        keep = t >= self.settle
        err = np.linalg.norm((com - ref)[keep], axis=1)
        return {"com_rms_error_m": float(np.sqrt(np.mean(err ** 2))), "com_max_error_m": float(err.max())}


class OneFootScenario(Scenario):
    """Shift the CoM over one foot, lift the other `lift` m, hold it, until the end.

    params: support (left|right), shift_time [s], lift [m], lift_time [s].
    """

    kind = "one-foot"

    def parse(self, params):
        self.support = Side(params.str("support", "left", choices=["left", "right"]))
        self.shift_time = params.float("shift_time", 1.5, positive=True)
        self.lift = params.float("lift", 0.05, min=0.0)
        self.lift_time = params.float("lift_time", 1.0, positive=True)

    def setup(self, q0, com0):
        super().setup(q0, com0)
        import pinocchio as pin
        data = self.robot.model.createData()
        pin.framesForwardKinematics(self.robot.model, data, q0)
        self.feet0 = {s: data.oMf[self.robot.sole_frame_id(s)].copy() for s in Side}
        self.swing = Side.RIGHT if self.support is Side.LEFT else Side.LEFT
        target = self.feet0[self.support].translation
        self.com_target = np.array([target[0], target[1], com0[2]])

    def references(self, t):
        s, ds, dds = _min_jerk(t / self.shift_time)
        d = self.com_target - self.com0
        com, com_vel, com_acc = self.com0 + s * d, d * ds / self.shift_time, d * dds / self.shift_time ** 2
        contacts = frozenset(Side)
        feet = {}
        lift_off = {self.swing: self.shift_time} if t < self.shift_time else {}
        if t >= self.shift_time:
            contacts = frozenset({self.support})
            u, du, ddu = _min_jerk((t - self.shift_time) / self.lift_time)
            p0 = self.feet0[self.swing].translation
            up = np.array([0, 0, self.lift])
            feet[self.swing] = PoseReference.translating(p0 + u * up, up * du / self.lift_time,
                                                         up * ddu / self.lift_time ** 2)
        # the ZMP of this CoM motion on the cart-table model: p = c - (c_z / g) c_ddot
        zmp = np.array([*(com[:2] - (com[2] - self.ground_height()) / GRAVITY * com_acc[:2]), self.ground_height()])
        return References(t=t, contacts=contacts, com=PointReference(com, com_vel, com_acc), feet=feet, zmp=zmp,
                          lift_off=lift_off)

    def metrics(self, log):
        com = channel(log, "com")
        ref = channel(log, "com_ref")
        err = np.linalg.norm(com - ref, axis=1)
        return {"com_rms_error_m": float(np.sqrt(np.mean(err ** 2))), "com_max_error_m": float(err.max())}


class PostureSinusoidScenario(Scenario):
    """Both feet in contact, a sinusoidal joint motion (an arm's) under the posture task: paper 000's Section 7.3.2
    experiment (the Table 9 task set: the feet's contacts and the posture task, with the Table 10 gains).

    The posture task named `task` (default ``posture``) follows q0 with `joints`' angles moved by
    ``amplitude * sin(2 pi f t)``, the amplitude ramped in over `ramp` seconds (a min-jerk envelope, so that the
    reference starts at rest). The run `diverged` when a joint leaves its reference by more than
    `divergence_error` [rad], exceeds its velocity limit or reaches a position limit (the real robot's harmonic
    drives blocked at the limits; angles on the link side: with `--realism`, the encoders' angle plus the hidden
    deflections), or the robot fell (the summary's `fell`). `chatter_rad_s`: the largest RMS velocity, after the ramp,
    of a joint the sinusoid does not move (an oscillation that need not diverge: high gains on an elastic drive).

    params: joints {joint name: amplitude [rad]}, frequency [Hz], ramp [s], divergence_error [rad], task.
    """

    kind = "posture-sinusoid"

    def parse(self, params):
        joints = params.raw("joints", {"arm_right_1_joint": 0.2, "arm_right_4_joint": -0.4})
        names = self.robot.joint_names
        if not isinstance(joints, dict) or not joints:
            raise params.error("joints", f"must be a mapping joint name -> amplitude [rad], got {joints!r}")
        self.moved = []
        for name, amp in joints.items():
            if name not in names:
                raise UnknownNameError("joint", str(name), names, file=params.file, key=params.key("joints"))
            if isinstance(amp, bool) or not isinstance(amp, (int, float)) or not np.isfinite(amp):
                raise params.error("joints", f"amplitude of {name} must be a number [rad], got {amp!r}")
            self.moved.append((names.index(name), float(amp)))
        self.frequency = params.float("frequency", 0.5, positive=True)
        self.ramp = params.float("ramp", 1.0, min=0.0)
        self.divergence_error = params.float("divergence_error", 0.2, positive=True)
        self.task = params.str("task", "posture")

    def setup(self, q0, com0):
        super().setup(q0, com0)
        self._idx = np.array([i for i, _ in self.moved], dtype=int)
        self._amp = np.array([a for _, a in self.moved])
        lo, hi = self.robot.position_limits
        bad = [f"{self.robot.joint_names[i]} ({q0[7 + i] - abs(a):.3f}..{q0[7 + i] + abs(a):.3f} rad, limits "
               f"{lo[i]:.3f}..{hi[i]:.3f})" for i, a in self.moved
               if q0[7 + i] - abs(a) < lo[i] or q0[7 + i] + abs(a) > hi[i]]
        if bad:
            raise ConfigError(f"the sinusoid leaves the position limits: {'; '.join(bad)}", file=self.spec.file,
                              key="params.joints")

    def _offsets(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The moved joints' offsets from q0 at t: angle, velocity, acceleration."""
        w = 2.0 * np.pi * self.frequency
        s, c = np.sin(w * t), np.cos(w * t)
        e, de, dde = _min_jerk(t / self.ramp) if self.ramp > 0 else (1.0, 0.0, 0.0)
        if self.ramp > 0:
            de, dde = de / self.ramp, dde / self.ramp ** 2
        a = self._amp
        return a * e * s, a * (de * s + e * w * c), a * (dde * s + 2.0 * de * w * c - e * w * w * s)

    def reference_posture(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The posture reference's joint angles, velocities and accelerations (na,) at t."""
        dq, dv, da = self._offsets(t)
        q = self.q0[7:].copy()
        v, a = np.zeros_like(q), np.zeros_like(q)
        q[self._idx] += dq
        v[self._idx], a[self._idx] = dv, da
        return q, v, a

    def references(self, t: float) -> References:
        q, v, a = self.reference_posture(t)
        config = self.q0.copy()
        config[7:] = q
        return References(t=t, contacts=frozenset(Side), targets={self.task: JointReference(config, v, a)})

    def metrics(self, log):
        names = self.robot.joint_names
        t = log["t"]
        q = channel(log, "q")[:, 7:].copy()
        v = channel(log, "v")[:, 6:]
        # the link side, where a drive blocks: the encoders' (motor side) angle plus any hidden deflection of the
        # realistic robot (`--realism`: the drive's spring `<joint>:drive`, the hip's `<joint>:hip_flex`)
        for k, col in log.items():
            if k.startswith("hidden_deflection."):
                joint = k.split(".", 1)[1].rsplit(":", 1)[0]
                if joint in names:
                    q[:, names.index(joint)] += np.asarray(col)
        refs = [self.reference_posture(float(ti)) for ti in t]
        ref = np.array([r[0] for r in refs])
        v_ref = np.array([r[1] for r in refs])
        err = np.abs(q - ref)
        lo, hi = self.robot.position_limits
        vmax = self.robot.velocity_limit
        margin = 1e-3   # [rad] from a position limit counts as reaching it
        bad = (err > self.divergence_error) | (np.abs(v) > vmax) | (q < lo + margin) | (q > hi - margin)
        tick = np.flatnonzero(bad.any(axis=1))
        out = {"posture_max_error_rad": float(err.max()),
               "posture_rms_error_rad": float(np.sqrt(np.mean(err[:, self._idx] ** 2))),
               "max_joint_speed_ratio": float(np.max(np.abs(v) / vmax)),
               "diverged": bool(tick.size)}
        # chatter: the velocity of the joints the sinusoid does not move, after the ramp, RMS per joint (legs that
        # should stand still oscillating under high gains and an elastic drive); the largest and its joint
        after = t >= self.ramp
        still = np.setdiff1d(np.arange(len(names)), self._idx)
        if after.any() and still.size:
            rms = np.full(len(names), -1.0)
            rms[still] = np.sqrt(np.mean(v[after][:, still] ** 2, axis=0))
            j = int(np.argmax(rms))
            out.update(chatter_rad_s=float(rms[j]), chatter_joint=names[j])
        if tick.size:
            k = int(tick[0])
            j = int(np.argmax(np.where(bad[k], err[k], -1.0)))
            out.update(divergence_time_s=float(t[k]), divergence_joint=names[j])
        return out


def _min_jerk(s: float) -> tuple[float, float, float]:
    """Minimum-jerk profile on [0, 1]: value, first and second derivative w.r.t. s (clamped outside)."""
    if s <= 0:
        return 0.0, 0.0, 0.0
    if s >= 1:
        return 1.0, 0.0, 0.0
    return (10 * s**3 - 15 * s**4 + 6 * s**5, 30 * s**2 - 60 * s**3 + 30 * s**4, 60 * s - 180 * s**2 + 120 * s**3)


class WalkScenario(Scenario):
    """Walk on flat ground: a footstep plan, ZMP preview control (Kajita 2003) for the CoM, quintic swing feet.

    params: steps (number of steps before the final one), step_length [m], single_support and
    double_support [s], initial_double_support / final_double_support [s], apex [m] (swing apex height),
    first_side (left|right), step_width (default: the feet's initial separation), max_step_length [m] (the
    reach limit the plan is checked against, default 0.65), com_height [m] (the CoM height above the soles while
    walking, default: the initial one; a lower one is reached by a quintic descent during the initial double
    support, before the ZMP first moves, and the preview controller's cart-table height is set to it),
    swing_pitch_max [rad] (the bound of the swing-foot pitch the references offer, `References.swing_pitch`, see
    wbcbench.planning.swing_pitch; default 0.3, 0: none offered), toe_off [s] (the longest roll of a leaving foot
    about its toe edge before its lift-off, with the swing's pitch about that edge: `toe_off_offsets`; default 0,
    none; not with the file's own step_adjustment, an error; a walk whose step adjustment is switched on otherwise
    plans none).
    step_adjustment: {...} (off when absent): DCM-based step adjustment (wbcbench.planning.step_adjustment); keys
    enabled (default true), threshold [m], period [s], adapt_timing, min_single_support / max_single_support /
    min_remaining [s], max_forward / max_backward / max_lateral / min_clearance [m] (default: the robot profile's
    `stepping`), w_step, w_time, w_offset, min_change [m], contact_force [N], deadband [m], replan_from
    (measured|planned|dcm), late_descent (a share of a re-planned swing's remaining time, < 1), late_descent_back
    (true: the late descent only for a swing foot sent back behind itself). Keys the file
    leaves come from the controller's task set (`step_adjustment:`, see `adopt_step_adjustment`), else the
    defaults. Each tick the scenario gets the Measurement (`observe`), and the
    re-planned references replace the walk's.
    The scenario's duration is the plan's unless the file or --duration sets one (a shorter duration cuts the
    walk; metrics then compare with where the plan is at that time).
    """

    kind = "walk"
    #: the online step adjuster (None: off)
    adjuster = None
    step_adjustment = None
    _step_adjustment_given: frozenset = frozenset()  # the keys the scenario's own section sets
    supports_step_adjustment = True

    def parse(self, params):
        self.n_steps = params.int("steps", min=0)
        self.step_length = params.float("step_length")
        self.single = params.float("single_support", positive=True)
        self.double = params.float("double_support", positive=True)
        self.initial_ds = params.float("initial_double_support", 3.5, positive=True)
        self.final_ds = params.float("final_double_support", 2.0, positive=True)
        self.apex = params.float("apex", 0.05, min=0.0)
        self.first = params.str("first_side", "right", choices=["left", "right"])
        self.width = params.float("step_width", 0.0, min=0.0)
        self.preview_horizon = params.float("preview_horizon", 2.5, positive=True)
        self.max_step_length = params.float("max_step_length", 0.65, positive=True)
        self.swing_pitch_max = params.float("swing_pitch_max", 0.3, min=0.0)
        self.toe_off = params.float("toe_off", 0.0, min=0.0)
        self.com_height = params.float("com_height", positive=True) if params.has("com_height") else None
        if params.has("step_adjustment") and self.toe_off > 0.0:
            raise ConfigError("toe_off and step_adjustment do not go together (a re-plan does not continue a "
                              "toe-off under way): set toe_off: 0 or remove step_adjustment",
                              file=self.spec.file, key="params.toe_off")
        if params.has("step_adjustment"):
            self.step_adjustment, self._step_adjustment_given = _parse_step_adjustment(
                params.section("step_adjustment"), self.robot)

    def enable_step_adjustment(self, config=None) -> None:
        """Switch the step adjustment on (before `setup`), with `config` or the defaults and the robot's limits."""
        from ..planning.step_adjustment import StepAdjustmentConfig
        if not self.supports_step_adjustment:
            raise ConfigError(f"step adjustment works on flat `walk` scenarios, not kind '{self.kind}'",
                              file=self.spec.file, key="--step-adjustment")
        self.step_adjustment = config or StepAdjustmentConfig.from_stepping(self.robot.profile.stepping)
        self._step_adjustment_given = frozenset()

    def adopt_step_adjustment(self, settings: dict, source: str = "") -> None:
        """The controller's own step-adjustment settings (its task set's `step_adjustment:` section, e.g. a
        position-controlled scheme whose stabilizer absorbs part of the DCM error), for every key the scenario
        does not set itself; nothing when the step adjustment is off. Before `setup`."""
        if self.step_adjustment is None or not settings:
            return
        kw = {k: v for k, v in settings.items() if k not in self._step_adjustment_given}
        try:
            self.step_adjustment = replace(self.step_adjustment, **kw)
        except PlanningError as exc:
            raise ConfigError(f"step adjustment: {exc}", file=source or self.spec.file,
                              key="step_adjustment") from None

    def setup(self, q0, com0):
        import pinocchio as pin

        from ..planning import (PatternGeneratorConfig, ReachLimits, SoleRectangle, StepTiming, generate_walk,
                                straight_walk)
        super().setup(q0, com0)
        data = self.robot.model.createData()
        pin.framesForwardKinematics(self.robot.model, data, q0)
        feet = {s: data.oMf[self.robot.sole_frame_id(s)] for s in Side}
        mid = (feet[Side.LEFT].translation + feet[Side.RIGHT].translation) / 2
        sep = self.width or float(np.linalg.norm(feet[Side.LEFT].translation - feet[Side.RIGHT].translation))
        sole = self.robot.profile.sole
        try:
            plan = straight_walk(self.n_steps, self.step_length, foot_separation=sep,
                                 timing=StepTiming(self.single, self.double, self.initial_ds, self.final_ds),
                                 sole=SoleRectangle(sole.length, sole.width, *sole.center),
                                 first_side=Side(self.first), start=(mid[0], mid[1], mid[2], 0.0),
                                 limits=ReachLimits(max_length=self.max_step_length))
            h0 = float(com0[2] - mid[2])
            self.pg_config = PatternGeneratorConfig(
                com_height=h0 if self.com_height is None else self.com_height, dt=self.spec.control_dt,
                swing_apex_height=self.apex, preview_horizon=self.preview_horizon,
                initial_com_height=None if self.com_height is None else h0)
            self.walk = generate_walk(plan, self.pg_config, p_world_com_init=com0)
        except PlanningError as exc:  # the one point where a plan's error gets the scenario's file and key
            raise ConfigError(f"invalid walk: {exc}", file=self.spec.file, key="params") from None
        self.plan = plan
        self.base_offset = q0[:3] - com0
        self.legs = self.swing_pitch = None
        if self.swing_pitch_max > 0.0 and self.offer_swing_pitch:
            from ..planning.swing_pitch import LegGeometry, SwingPitchConfig
            try:
                self.legs = LegGeometry.from_robot(self.robot, q0, com0)
                # a walk re-planned online (step adjustment, e.g. switched on by --step-adjustment) plans no toe-off
                toe_off = self.toe_off if self.step_adjustment is None else 0.0
                self.swing_pitch = SwingPitchConfig(max_pitch=self.swing_pitch_max, toe_off=toe_off)
            except PlanningError:  # a model without an ankle-knee-hip chain: no swing pitch offered
                self.legs = self.swing_pitch = None
        self.adjuster = None
        if self.step_adjustment is not None:
            from ..planning.step_adjustment import StepAdjuster
            self.adjuster = StepAdjuster(self.walk, self.step_adjustment, self.pg_config, sep)
            self._data = self.robot.model.createData()
            from ..estimation.feet import FeetSensing
            self._feet = FeetSensing(self.robot)

    def observe(self, t: float, meas) -> None:
        """The measurement of this tick (what the controller sees): with step adjustment on, the DCM from the
        measured configuration and velocity (wbcbench.estimation.dcm) against the plan's, and the feet the ankle
        F/T sensors find loaded; a re-plan replaces the walk's references from this tick on."""
        if self.adjuster is None:
            return
        import pinocchio as pin

        from ..estimation import dcm
        w = self.walk
        k = min(int(round(t / w.dt)), w.n_ticks - 1)
        pin.centerOfMass(self.robot.model, self._data, meas.q, meas.v)
        com, vcom = self._data.com[0], self._data.vcom[0]
        xi = dcm(com, vcom, w.omega)
        # the LIPM acceleration about this tick's planned ZMP (the stance sole in single support)
        acc = w.omega ** 2 * (com[:2] - w.p_world_zmp_ref[k, :2])
        # the feet the ankle F/T sensors find loaded (vertical ground force, the foot below the sensor removed)
        feet = self._feet
        for fid in feet.sensor_ids.values():
            pin.updateFramePlacement(self.robot.model, self._data, fid)
        fmin = self.step_adjustment.contact_force
        loaded = frozenset(s for s, f in feet.vertical_forces(meas, self._data).items() if f > fmin)
        new = self.adjuster.update(int(round(t / w.dt)), xi[:2], np.vstack([com[:2], vcom[:2], acc]), loaded)
        if new is not None:
            self.walk = new

    def log_channels(self) -> dict:
        if self.step_adjustment is None:    # asked before `setup`: the switch, not the adjuster, decides
            return {}
        from ..planning.step_adjustment import StepAdjuster
        return {"step_adjustment": list(StepAdjuster.LOG_LABELS)}

    def log_values(self) -> list:
        return [self.adjuster.log] if self.adjuster is not None else []

    @property
    def planned_duration(self) -> float:
        return self.walk.duration

    def references(self, t):
        w = self.walk
        table = self._table
        k = min(int(round(t / w.dt)), w.n_ticks - 1)
        if table is None or table.walk is not w:
            table = self._tabulate(w, None if table is None else (k, table.pitch))
        i = k - table.k0  # among the references made ahead (`_WalkTable.make_ahead`)?
        if 0 <= i < len(table.ahead):
            ref = table.ahead[i]
            if ref.t == t:
                return ref
        return table.make_ahead(t, k)

    _table = None

    #: the leg geometry and settings of the swing pitch offered with the references (`References.swing_pitch`), set
    #: by `setup` (None: none offered)
    legs = swing_pitch = None
    #: whether `setup` plans the swing pitch at all (about 20 ms a walk, and again at each re-plan): a run whose
    #: controller's task set does not take it switches it off (`runner`); other callers get it
    offer_swing_pitch = True

    def _tabulate(self, walk, previous=None) -> "_WalkTable":
        """The table of `walk`; previous: (tick, the swing pitch of the table it replaces from that tick on)."""
        self._table = _WalkTable(walk, self.legs, self.swing_pitch,
                                 previous if previous is not None and previous[1] is not None else None)
        return self._table

    def metrics(self, log):
        com = channel(log, "com")
        ref = channel(log, "com_ref")
        err = np.linalg.norm(com - ref, axis=1)
        t_end = log["t"][-1]
        k = min(int(round(t_end / self.walk.dt)), self.walk.n_ticks - 1)
        planned_base = self.walk.p_world_com[k] + self.base_offset
        base = np.array([log["q.x"][-1], log["q.y"][-1]])
        start = np.array([log["q.x"][0], log["q.y"][0]])
        out = {"com_rms_error_m": float(np.sqrt(np.mean(err ** 2))), "com_max_error_m": float(err.max()),
               "final_position_error_m": float(np.linalg.norm(base - planned_base[:2])),
               "distance_m": float(np.linalg.norm(base - start)),
               "planned_distance_m": float(np.linalg.norm(planned_base[:2] - start))}
        if self.adjuster is not None:  # the plan above is the re-planned one
            out["step_adjustments"] = self.adjuster.count
            out["step_adjustment_foothold_shift_m"] = [float(x) for x in self.adjuster.delta]
        return out


class _WalkTable:
    """A walk's references, tick by tick, from arrays arranged once per walk (a re-plan makes a new walk): the
    contact set of every tick, the swing feet's 6-D velocities and accelerations (linear, zero angular), the
    planned lift-offs ahead (`References.lift_off`: one dict per stance phase, shared by its ticks), the swing
    pitch offered with the swing feet (`References.swing_pitch`, from `legs` and `pitch_config`, continuing a
    replaced table's `previous` (tick, pitch) through a re-plan; None: none offered), and the rows
    that `references` hands out as they are (the plan's arrays, checked here once)."""

    def __init__(self, walk, legs=None, pitch_config=None, previous=None):
        self.walk = walk
        n = walk.n_ticks
        self.com = tuple(_checked_rows(a, (3,), "CoM") for a in (walk.p_world_com, walk.v_world_com, walk.a_world_com))
        self.zmp = _checked_rows(walk.p_world_zmp_ref, (3,), "ZMP")
        pitch = None
        if legs is not None:
            from ..planning.swing_pitch import plan_swing_pitch
            pitch = plan_swing_pitch(walk, legs, pitch_config, previous)
        self.pitch = pitch
        toe_off = pitch is not None and pitch[Side.LEFT].shape[1] > 3
        code = np.zeros(n, dtype=np.int64)
        feet = {}
        offer = {}
        roll = np.zeros(n, dtype=bool)
        for bit, s in enumerate(Side):
            f = walk.feet[s]
            contact = np.asarray(f.in_contact[:n], dtype=bool)
            code += contact.astype(np.int64) << bit
            zeros = np.zeros((n, 3))
            p, v, a = f.p_world_sole[:n], f.v_world_sole[:n], f.a_world_sole[:n]
            if toe_off:
                # a toe-off's swing turns about the toe: the sole's origin goes where that turn puts it (the swing's
                # planned path), the turn itself is offered about the origin; in contact, the roll about the toe
                from ..planning.swing_pitch import about_edge_offset
                do = about_edge_offset(f.R_world_sole[:n], pitch[s][:n], ~contact)
                p, v, a = p + do[0], v + do[1], a + do[2]
                offer[s] = pitch[s][:n].copy()
                offer[s][~contact, 3] = 0.0
                roll |= (pitch[s][:n, 3] != 0.0) & contact
            feet[s] = (_checked_rows(p, (3,), "foot position"),
                       _checked_rows(f.R_world_sole, (3, 3), "foot rotation"),
                       _checked_rows(np.hstack([v, zeros]), (6,), "foot velocity"),
                       _checked_rows(np.hstack([a, zeros]), (6,), "foot acceleration"))
        self.code = code.tolist()
        self.lift_off = _lift_off_by_tick([walk.feet[s].in_contact[:n] for s in Side], walk.dt)
        # what the references offer (a toe-off's: the swings' pitch about the origin, the rolls' about the toe)
        self.offer = offer if toe_off else pitch
        # the ticks on which a foot in contact turns about its toe (a toe-off)
        self.rolling = roll.tolist() if toe_off else [False] * n
        # per contact code: the contact set and the (side, arrays) of the swinging feet
        self.contacts = [frozenset(s for bit, s in enumerate(Side) if c >> bit & 1) for c in range(1 << len(Side))]
        self.swinging = [[(s, feet[s]) for bit, s in enumerate(Side) if not c >> bit & 1]
                         for c in range(1 << len(Side))]

    #: ticks whose references are made together: a tick's few small objects cost about half as much made in a
    #: burst as one by one between a controller's step and the physics (which leave the caches cold)
    AHEAD = 50

    #: the references of ticks k0, k0 + 1, ... made ahead (at times j dt: a caller asking at another time of a
    #: tick gets a new one)
    k0, ahead = 0, ()

    def make_ahead(self, t: float, k: int) -> References:
        """The references of tick k at time t, and those of the next `AHEAD` - 1 ticks kept in `ahead`."""
        ahead = [self._make(t, k)]
        dt = self.walk.dt
        for j in range(k + 1, min(k + self.AHEAD, self.walk.n_ticks)):
            ahead.append(self._make(j * dt, j))
        self.k0, self.ahead = k, ahead
        return ahead[0]

    def _make(self, t: float, k: int) -> References:
        code = self.code[k]
        feet = {}
        for s, (p, R, v, a) in self.swinging[code]:
            feet[s] = PoseReference.unchecked(p[k], R[k], v[k], a[k])
        pitch = self.offer
        if pitch is not None and self.rolling[k]:  # a toe-off: the leaving foot turns about its toe, in contact
            pitch = {s: pitch[s][k] for s in Side if s in feet or pitch[s][k, 3] != 0.0}
        else:
            pitch = {s: pitch[s][k] for s in feet} if pitch is not None and feet else None
        p, v, a = self.com
        return References.planned(t, self.contacts[code], PointReference.unchecked(p[k], v[k], a[k]), self.zmp[k],
                                  feet, None, self.lift_off[k], pitch)


def _lift_off_by_tick(in_contact: list, dt: float) -> list[dict]:
    """Per tick, {side: time [s] of the side's next planned lift-off} for the sides in contact then with one
    ahead (a lift-off: the first tick out of contact after a tick in contact); the ticks of one stance phase
    share one dict."""
    n = len(in_contact[0])
    nxt = []
    for c in in_contact:
        c = np.asarray(c, dtype=bool)
        lift = np.flatnonzero(c[:-1] & ~c[1:]) + 1  # the ticks whose foot has just left the ground
        j = np.searchsorted(lift, np.arange(n), side="right")  # the first lift-off after each tick
        k = np.where(j < len(lift), lift[np.minimum(j, len(lift) - 1)] if len(lift) else -1, -1)
        nxt.append(np.where(c, k, -1).tolist())
    shared: dict = {}
    out = []
    for key in zip(*nxt):
        d = shared.get(key)
        if d is None:
            d = shared[key] = {s: k * dt for s, k in zip(Side, key) if k >= 0}
        out.append(d)
    return out


def _checked_rows(a, shape: tuple, what: str) -> np.ndarray:
    """A plan's per-tick array as float64, C-ordered (each row a contiguous view), rows of `shape`."""
    out = np.ascontiguousarray(a, dtype=np.float64)
    if out.shape[1:] != shape:
        raise ValueError(f"walk {what}: rows of shape {out.shape[1:]}, expected {shape}")
    return out


def _parse_step_adjustment(sec, robot):
    """The walk's `step_adjustment:` section -> (StepAdjustmentConfig, the keys it gives), or (None, {}) when
    `enabled: false`."""
    from ..planning.step_adjustment import StepAdjustmentConfig, parse_settings
    if not sec.bool("enabled", True):
        for k in list(sec.data):
            sec.raw(k)
        return None, frozenset()
    given = frozenset(k for k in sec.data if k != "enabled")
    kw = parse_settings(sec, StepAdjustmentConfig.from_stepping(robot.profile.stepping))
    sec.finish()
    try:
        return StepAdjustmentConfig(**kw), given
    except PlanningError as exc:
        raise sec.error(None, str(exc)) from None


class TerrainWalkScenario(WalkScenario):
    """Walk across uneven terrain (tilted platforms, stairs): the scene's boxes become contact surfaces, a
    foothold planner (or explicit placements) gives the contact sequence, a centroidal QP the CoM and contact
    wrenches, and terrain-clearing swings the feet (wbcbench.planning.multicontact).

    params: goal [x, y] (final feet midpoint) or placements [[side, x, y], ...]; single_support,
    double_support, initial_double_support, final_double_support [s]; swing_clearance [m]; friction (mu of
    the planner, default 0.5); max_step_length / max_step_height [m]; max_leg_extension: largest hip-ankle
    distance the centroidal plan may ask for, as a fraction of the straight leg (default: the profile's
    `stepping.max_leg_extension`, else 0.94, about what TALOS' flat walks use; 0 switches the bound off);
    max_swing_leg_extension: the same for a swinging leg, at the swing's planned pose (default 0: off, a swinging
    leg unbounded; `stairs` uses 0.96: without it the CoM rose after each lift-off faster than the swinging foot,
    the swing knee straightened, then bent again, and at the last step ran into its limit);
    com_height [m]: the CoM height above the support the centroidal plan aims at (default, or null: the initial one; a
    lower one is reached during the initial double support).
    """

    kind = "terrain-walk"
    supports_step_adjustment = False

    def parse(self, params):
        self.goal = params.vector("goal", length=2) if params.has("goal") else None
        raw = params.list("placements", [])
        self.placements = []
        for i, p in enumerate(raw):
            if not (isinstance(p, list) and len(p) in (3, 4) and p[0] in ("left", "right")):
                raise params.error("placements", f"entry {i} must be [left|right, x, y(, yaw)], got {p!r}")
            self.placements.append((Side(p[0]), *map(float, p[1:])))
        if self.goal is None and not self.placements:
            raise params.error("goal", "give a goal [x, y] or explicit placements")
        self.single = params.float("single_support", positive=True)
        self.double = params.float("double_support", positive=True)
        self.initial_ds = params.float("initial_double_support", 1.5, positive=True)
        self.final_ds = params.float("final_double_support", 2.0, positive=True)
        self.clearance = params.float("swing_clearance", 0.05, min=0.0)
        self.friction = params.float("friction", 0.5, positive=True)
        self.max_step_length = params.float("max_step_length", 0.30, positive=True)
        self.max_step_height = params.float("max_step_height", 0.15, positive=True)
        reach = self.robot.profile.stepping.max_leg_extension
        self.max_leg_extension = params.float("max_leg_extension", 0.94 if reach is None else reach, min=0.0, max=1.0)
        self.max_swing_leg_extension = params.float("max_swing_leg_extension", 0.0, min=0.0, max=1.0)
        # null: the standing height (a robot profile's sizes may give it to undo a scenario file's height)
        self.com_height = (params.float("com_height", positive=True) if params.raw("com_height", None) is not None
                           else None)

    def _leg_reach(self, q0, com0):
        """The robot's `LegReach` at q0 (hip: first joint of each leg, ankle: the sole's joint; straight leg: the
        leg joints at their neutral value), or None."""
        import pinocchio as pin

        from ..planning.centroidal import LegReach
        from ..planning.geometry import rotation_from_yaw, yaw_of
        if self.max_leg_extension <= 0.0:
            return None
        m = self.robot.model
        d, d_straight = m.createData(), m.createData()
        pin.framesForwardKinematics(m, d, q0)
        neutral, q_straight = pin.neutral(m), q0.copy()
        hip, ankle, joints = {}, {}, {}
        for s in Side:
            sole = self.robot.sole_frame_id(s)
            M_sole = d.oMf[sole]
            j_ankle = m.frames[sole].parentJoint
            chain = m.supports[j_ankle][2:]      # supports: [universe, root, first leg joint, ...]
            joints[s] = (chain[0], j_ankle)
            hip[s] = rotation_from_yaw(yaw_of(M_sole.rotation)).T @ (d.oMi[chain[0]].translation - com0)
            ankle[s] = M_sole.actInv(d.oMi[j_ankle].translation)
            for j in chain:
                idx = slice(m.joints[j].idx_q, m.joints[j].idx_q + m.joints[j].nq)
                q_straight[idx] = neutral[idx]
        pin.forwardKinematics(m, d_straight, q_straight)
        length = min(float(np.linalg.norm(d_straight.oMi[h].translation - d_straight.oMi[a].translation))
                     for h, a in joints.values())
        return LegReach(hip, ankle, self.max_leg_extension * length,
                        self.max_swing_leg_extension * length if self.max_swing_leg_extension > 0.0 else None)

    def setup(self, q0, com0):
        import pinocchio as pin

        from ..planning import Footstep, SoleRectangle, StepTiming
        from ..planning.centroidal import CentroidalConfig
        from ..planning.contact_planner import ContactPlannerConfig, contacts_from_placements, plan_contacts
        from ..planning.multicontact import generate_multicontact_walk
        from ..planning.terrain import ContactTerrain
        Scenario.setup(self, q0, com0)
        data = self.robot.model.createData()
        pin.framesForwardKinematics(self.robot.model, data, q0)
        start = {}
        for s in Side:
            # the planner starts from level feet: position and heading of the soles (TALOS' half-sitting has a
            # 1.7 mrad ankle roll the contacts absorb), at the height of the highest sole corner (the ground the
            # tilted sole rests on; its origin is 0.11 mm lower)
            M = data.oMf[self.robot.sole_frame_id(s)]
            yaw = float(np.arctan2(M.rotation[1, 0], M.rotation[0, 0]))
            start[s] = Footstep.from_xyz_yaw(s, M.translation[0], M.translation[1],
                                             self.robot.sole_rest_height(data, s), yaw=yaw)
        sole = self.robot.profile.sole
        rect = SoleRectangle(sole.length, sole.width, *sole.center)
        timing = StepTiming(self.single, self.double, self.initial_ds, self.final_ds)
        ground = min(f.p_world_sole[2] for f in start.values())
        try:
            terrain = ContactTerrain.from_terrain(self.spec.terrain)
            sep = float(np.linalg.norm(start[Side.LEFT].p_world_sole[:2] - start[Side.RIGHT].p_world_sole[:2]))
            cfg = ContactPlannerConfig(max_step_length=self.max_step_length, max_step_height=self.max_step_height,
                                       foot_separation=sep)
            if self.placements:
                plan = contacts_from_placements(terrain, start, self.placements, timing=timing, sole=rect, config=cfg)
            else:
                plan = plan_contacts(terrain, start, self.goal, timing=timing, sole=rect, config=cfg)
            height = float(com0[2] - ground) if self.com_height is None else self.com_height
            walk = generate_multicontact_walk(
                plan, CentroidalConfig(mass=self.robot.mass, com_height=height,
                                       friction=self.friction, dt=self.spec.control_dt,
                                       leg_reach=self._leg_reach(q0, com0)),
                swing_clearance=self.clearance, p_world_com_init=com0)
        except PlanningError as exc:
            raise ConfigError(f"invalid terrain walk: {exc}", file=self.spec.file, key="params") from None
        self.contact_plan = plan
        self.walk = walk.walk
        self.base_offset = q0[:3] - com0


class CommandWalkScenario(WalkScenario):
    """Walk on flat ground following a velocity command or a path (wbcbench.planning.command): turns, side
    steps, backward steps; the robot profile's `stepping` section limits each step.

    The trunk's orientation task (named "waist" in the task sets) follows the walking frame's heading.
    params (one of): command [[t, vx, vy, yaw_rate], ...] (keyframes, piecewise linear, [s, m/s, m/s, rad/s],
    walking frame), command_csv (a CSV file t,vx,vy,yaw_rate, relative to the scenario file), path
    [[x, y, yaw_deg], ...] (waypoints in the start walking frame [m, m, deg], reached in turn).
    Also single_support, double_support, initial_double_support, final_double_support [s], apex [m],
    step_width, preview_horizon as `walk`.
    Metrics as `walk`, the base offset from the CoM turned with the walk, plus final_yaw_error_deg (base heading
    vs the plan's walking frame).
    """

    kind = "walk-command"
    supports_step_adjustment = False

    def parse(self, params):
        given = [k for k in ("command", "command_csv", "path") if params.has(k)]
        if len(given) != 1:
            raise params.error("command", f"give exactly one of command, command_csv, path (got {given or 'none'})")
        self.source = given[0]
        if self.source == "command_csv":
            from pathlib import Path
            raw = Path(params.str("command_csv"))
            self.source_value = raw if raw.is_absolute() or not self.spec.file else Path(self.spec.file).parent / raw
        else:
            rows = params.list(self.source)
            width = 4 if self.source == "command" else 3
            for i, r in enumerate(rows):
                if not (isinstance(r, list) and len(r) == width and all(
                        isinstance(v, (int, float)) and not isinstance(v, bool) for v in r)):
                    cols = "[t, vx, vy, yaw_rate]" if width == 4 else "[x, y, yaw_deg]"
                    raise params.error(self.source, f"entry {i} must be {cols} (numbers), got {r!r}")
            self.source_value = [list(map(float, r)) for r in rows]
        self.single = params.float("single_support", positive=True)
        self.double = params.float("double_support", positive=True)
        self.initial_ds = params.float("initial_double_support", 2.5, positive=True)
        self.final_ds = params.float("final_double_support", 2.0, positive=True)
        self.apex = params.float("apex", 0.05, min=0.0)
        self.width = params.float("step_width", 0.0, min=0.0)
        self.preview_horizon = params.float("preview_horizon", 1.6, positive=True)

    def setup(self, q0, com0):
        import pinocchio as pin

        from ..planning import PatternGeneratorConfig, SoleRectangle, StepTiming, generate_walk
        from ..planning.command import StepLimits, VelocityCommand, plan_from_command, plan_from_path
        from ..planning.geometry import yaw_of
        Scenario.setup(self, q0, com0)
        data = self.robot.model.createData()
        pin.framesForwardKinematics(self.robot.model, data, q0)
        feet = {s: data.oMf[self.robot.sole_frame_id(s)] for s in Side}
        mid = (feet[Side.LEFT].translation + feet[Side.RIGHT].translation) / 2
        yaw0 = float(np.mean([yaw_of(feet[s].rotation) for s in Side]))
        sep = self.width or float(np.linalg.norm(feet[Side.LEFT].translation - feet[Side.RIGHT].translation))
        sole = self.robot.profile.sole
        kw = dict(foot_separation=sep, timing=StepTiming(self.single, self.double, self.initial_ds, self.final_ds),
                  sole=SoleRectangle(sole.length, sole.width, *sole.center),
                  limits=StepLimits.from_profile(self.robot.profile.stepping), start=(*mid, yaw0))
        try:
            if self.source == "path":
                w = np.array(self.source_value)
                plan = plan_from_path(np.column_stack([w[:, :2], np.radians(w[:, 2])]), **kw)
            else:
                cmd = (VelocityCommand.from_csv(self.source_value) if self.source == "command_csv"
                       else VelocityCommand.from_rows(self.source_value))
                plan = plan_from_command(cmd, **kw)
            self.walk = generate_walk(plan, PatternGeneratorConfig(
                com_height=float(com0[2] - mid[2]), dt=self.spec.control_dt, swing_apex_height=self.apex,
                preview_horizon=self.preview_horizon), p_world_com_init=com0)
        except ValueError as exc:
            raise ConfigError(f"invalid walk: {exc}", file=self.spec.file, key=f"params.{self.source}") from None
        self.plan = plan
        self.yaw0 = yaw0
        # base position relative to the CoM in the walking frame, and base heading relative to it
        from ..planning.geometry import rotation_from_yaw
        self.base_offset_local = rotation_from_yaw(yaw0).T @ (q0[:3] - com0)
        self.base_yaw_offset = yaw_of(pin.Quaternion(q0[6], *q0[3:6]).toRotationMatrix()) - yaw0
        self.base_offset = q0[:3] - com0
        self.R_base0 = pin.Quaternion(q0[6], *q0[3:6]).toRotationMatrix()

    def references(self, t):
        import pinocchio as pin

        from ..planning.geometry import rotation_from_yaw
        refs = super().references(t)
        k = min(int(round(t / self.walk.dt)), self.walk.n_ticks - 1)
        # the waist (trunk orientation task "waist") turns with the feet: the walking frame's heading
        R = rotation_from_yaw(self._planned_frame_yaw(k) - self.yaw0) @ self.R_base0
        return replace(refs, targets={**refs.targets, "waist": PoseReference(np.zeros(3), R)})

    def _planned_frame_yaw(self, k: int) -> float:
        from ..planning.geometry import yaw_of
        yaws = np.unwrap([yaw_of(self.walk.feet[s].R_world_sole[k]) for s in Side])
        return float(np.mean(yaws))

    def metrics(self, log):
        import pinocchio as pin

        from ..planning.geometry import rotation_from_yaw, yaw_of
        out = super().metrics(log)
        t_end = log["t"][-1]
        k = min(int(round(t_end / self.walk.dt)), self.walk.n_ticks - 1)
        yaw_plan = self._planned_frame_yaw(k)
        planned_base = self.walk.p_world_com[k] + rotation_from_yaw(yaw_plan) @ self.base_offset_local
        base = np.array([log["q.x"][-1], log["q.y"][-1]])
        start = np.array([log["q.x"][0], log["q.y"][0]])
        quat = pin.Quaternion(log["q.qw"][-1], log["q.qx"][-1], log["q.qy"][-1], log["q.qz"][-1])
        yaw = yaw_of(quat.toRotationMatrix()) - self.base_yaw_offset
        out.update({"final_position_error_m": float(np.linalg.norm(base - planned_base[:2])),
                    "distance_m": float(np.linalg.norm(base - start)),
                    "planned_distance_m": float(np.linalg.norm(planned_base[:2] - start)),
                    "final_yaw_error_deg": float(np.degrees(abs((yaw - yaw_plan + np.pi) % (2 * np.pi) - np.pi))),
                    "planned_turn_deg": float(np.degrees(yaw_plan - self.yaw0))})
        return out
