"""The `teleop` scenario kind: whole-body teleoperation (paper 004), the operator's hands and head as references.

Both feet stay in contact and the CoM reference is held at its initial position (x-y; Table I's CoM task is
1 1 0). Each tick, the retargeted operator poses (`wbcbench.teleop.Retargeter`) at source time
`start + t * speed` become the references of the controller's named frame tasks through `References.targets`
(`targets` maps each effector to the tasks it feeds; the head feeds `head`, `head_pitch` and `head_yaw`).

params (YAML `params:` or `TeleopScenario.from_source`):
  mocap: a shipped recording name (`wbcbench teleop --list`), a .bvh/.mvnx/.csv file (relative to the scenario
    file), or `udp://HOST:PORT` for a live stream (datagram format in wbcbench/teleop/README.md).
  speed: playback factor (> 0) for recordings, default 1 (2: the motion twice as fast, paper Figure 2).
  start: source time [s] to start from (recordings), default: the first frame.
  proportion: robot/human scale, "shoulders" (default), "head" or a number (see the Retargeter).
  feedforward: true (default): recordings give the frame tasks the velocity and acceleration of the references
    (a C2 cubic spline through the retargeted frames, scipy's CubicSpline / RotationSpline); false: zero.
    Streams (live, or a recording through `network`) have their references from the newest received frame
    through a first-order low-pass (`smoothing` [s], default 0.03) so that 50-60 Hz steps do not reach the
    8000 s^-2 hand tasks as jumps, and feed forward the velocity of the last frames (through the same filter; no
    acceleration).
  on_loss: what the robot tracks while the source is invalid (stream stale or not started, file ended, frame
    without the effector): "hold" (default) the last valid targets; "reference" the effectors' poses in the
    reference posture, reached by a min-jerk blend over `return_time` s (default 2 s). Before any valid frame
    both are the reference poses.
  stale_after: a live stream is stale after this many seconds without a frame (default 0.2).
  anchor: where the operator's hand and head positions are put on the robot (orientations are always the
    retargeter's: calibrated so that the operator at rest gives the robot's own orientations, paper Section V).
    "absolute": the paper's absolute Cartesian teleoperation, the operator overlaid on the robot. With TALOS it
      puts the hands of an operator standing arms along the body 0.2-0.3 m medial of the robot's half-sitting
      grippers, inside the hips (0.2 m from the shoulder's vertical where TALOS' hanging arm, at its adduction
      limit, keeps the gripper 0.3 m out), and the head 6 cm above the robot's head: out of reach without
      interpenetration (the references the repulsors are for) and, for the head, reachable only on straight
      knees. On the 8 shipped recordings, repulsors off (benchmarks/teleop_table2.py --anchor absolute): 66 % of
      the hand ticks have their reference in the body, hand error 6.6 cm mean (2.6 cm where the reference is
      outside the body, 9.7-12 cm on arms_down and head_turning, whose hands rest all along), the QP's base
      raised 3-5 cm by the head target; the QP alone cannot take the arm through the hip (it stops at the
      shoulder's adduction limit).
    "offset": each effector's position reference is shifted by a constant so that at the calibration frame it
      equals the robot's own pose in its reference posture (relative teleoperation, what paper 004 contrasts
      itself with). Reaching sideways then asks for 0.23 m more than the arm has.
    "rest" (default): the "offset" shift near the calibration (rest) position, none far from it: the shift is
      weighted by 1 within `rest_blend[0]` of the operator's calibration position of that effector, by 0 beyond
      `rest_blend[1]` (default 0.10, 0.50 m), with a min-jerk profile between. The operator at rest is the robot
      at rest; hands reaching out (more than 0.5 m from their rest position) are overlaid absolutely, as in the
      paper. The head, which moves little, stays shifted to the robot's head height.
  rest_blend: [r_in, r_out] [m] of the "rest" anchor.
  engage_time: [s] (default 1): the references start at the robot's own effector poses and blend into the
    operator's with a min-jerk profile over this time (the operator's first pose is not the robot's: with
    TALOS the hands would jump 0.2-0.3 m into the hips at t = 0). 0: no blend. Metrics use the blended
    references (what the controller was asked to track).
  realtime: live streams only (default true): the run is paced so that simulated time does not run ahead of
    the wall clock.
  length_unit: a BVH file's length unit: auto (default: detected from the skeleton's standing extent), m, dm,
    cm, mm, in, ft, or metres per unit. up_axis: auto (default), x, y or z (the detection's vertical).
  segment_map: a YAML file `canonical MVN segment name: the file's segment name` when neither the names nor the
    skeleton's chains identify the segments (wbcbench/teleop/skeleton_map.py).
  safety: the command filter between the operator and the controller (wbcbench/teleop/safety.py): garbage held
    out, references pushed out of the body, jumps re-joined smoothly, speeds and accelerations clipped; keys
    enabled (default true), max_speed [m/s] (4), max_angular_speed [rad/s] (10), max_acceleration [m/s^2] (150),
    max_angular_acceleration [rad/s^2] (500), jump_distance [m] (0.05 per tick), jump_angle [rad] (0.3),
    rejoin_speed [m/s] (0.5), rejoin_angular_speed [rad/s] (1.5), min_rejoin_time [s] (0.3), body (default:
    on, off with anchor absolute), body_margin [m] (0.03), body_period [s] (0.005: how often the body spheres
    follow the measured posture; 0 every tick), hand_angular_speed [rad/s] (default none: the hands' turning held
    to max_angular_speed only; `wrist`: to what the robot's wrist can do, the norm of the velocity limits of the
    hand's last three joints, TALOS' 3.16). Interventions: the `teleop_filter` log channel and
    `teleop.filter` in the summary.
  network: an impaired link between the operator and the robot (wbcbench/teleop/network.py), e.g.
    "latency=50ms,jitter=5ms,loss=5%,burst=3,reorder=2%,duplicate=1%,corrupt=1%,stall=0.5s@3s,seed=1". A recording
    is then replayed through the link in simulated time into the live receiver's own decoder (reproducible), and
    the hands' undelayed references are logged (`teleop_truth`) and measured against; a `udp://HOST:PORT`
    stream passes through a loopback relay listening on HOST:PORT. Default: none.
  predict: none (default), velocity or spline: streams extrapolate the newest frame over its age plus the
    filter's lag (wbcbench/teleop/prediction.py), at most `predict_horizon` [s] (default 0.15); `predict_latency`
    [s] (default 0): a live stream's one-way latency the receiver cannot observe, added to the frames' age. Each
    tick's age and horizon are in the `teleop_stream` log channel with the receiver's counters.
  targets: {effector: [task names]} (default left_hand -> [left_hand], right_hand -> [right_hand],
    head -> [head, head_pitch, head_yaw]).
  locomotion: an operator who walks (wbcbench/teleop/human/locomotion.py): "auto" (default: the operator's
    translation and yaw taken out when the pelvis travels more than 0.25 m or turns more than 20 deg, the robot
    stands), "feet_fixed" (always taken out), "off" (never), or "stepping" (recordings only): the walk is taken out
    of the upper body's references as with feet_fixed, the operator's steps are detected and scaled, and the robot
    takes them through the walking stack (footstep limits of the profile's `stepping`, ZMP preview control, swing
    feet: wbcbench/teleop/session/stepping.py); the hands' and head's references are carried by the robot's
    walking frame (the planned CoM's horizontal position and the feet's mean heading), the trunk's orientation
    task `waist` turns with it.
    Use a task set that walks (`wbcbench teleop --locomotion stepping` takes tasksets/<robot>/teleop-stepping.yaml).
  stepping: {single_support, double_support, final_double_support, preview_horizon, initial_shift [s], apex [m],
    latency [s], catch_up (robot step pairs that reach a placement beyond the step limits, default 3; 0 clamps),
    step_adjustment (bool, default false: the walk's DCM-based step adjustment, with the profile's limits and the
    task set's `step_adjustment:` settings)} for `locomotion: stepping` (`SteppingConfig`).

Metrics (summary.json `metrics`), from the log's ground-truth configuration against the reference the
controller was given at each tick: `hand_position_error_m` and `hand_rotation_error` (||I - R_ref R^T||_F,
paper Table II), each {mean, std, min, max} over both hands and all ticks, the same per hand
(`hand_errors`); the same restricted to the ticks whose reference lies outside the robot's body
(`hand_position_error_outside_body_m`, `hand_rotation_error_outside_body`: the reference's protected point,
the gripper centre of the profile's `repulsors`, farther than r_rep + r_frame from every repulsion point at the
robot's configuration of that tick) and the fraction inside (`hand_reference_inside_body_fraction`): a
reference inside the hips cannot be tracked without interpenetration, whatever the controller; every 10 ms,
the same split by reachability (wbcbench/teleop/human/reachability.py: whether the effector's own chain, an arm
from where the torso was, can put it at its reference within the joint limits): `hand_position_error_reachable_m`
(reachable and outside the body), `hand_position_error_out_of_reach_m`, `hand_reachable_fraction`, the ticks
whose reference is reachable in time (a follower of it that moves the arm's joints at most at their velocity
limits is there: `hand_position_error_reachable_in_time_m`, `hand_reachable_in_time_fraction`), and the head's
(`head_position_error_reachable_m`, `head_position_error_out_of_reach_m`, `head_reachable_fraction`);
`head_position_error_m`; and `teleop` (invalid ticks, loss events and their duration, clamped ticks per
effector, the stream's receiver counters, the network link's counters and the prediction horizon). Through the
simulated link, also the hand errors against the undelayed reference (`hand_position_error_true_m`,
`hand_rotation_error_true`) and the reference's lag behind it (`hand_reference_lag_m`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from ..config import Section
from ..errors import ConfigError, UnknownNameError
from ..robots import Robot, Side
from ..types import PointReference, PoseReference, References
from ..teleop.source import (ANCHORS, DEFAULT_ANCHOR, DEFAULT_TARGETS, HANDS, REST_BLEND, TeleopReferenceSource,
                             TeleopSourceConfig, rotation_error, stats)
from .base import Scenario, ScenarioSpec
from .kinds import WalkScenario, _WalkTable

#: the `teleop_stream` log channel (live streams and the simulated link): the newest frame's age and the
#: prediction horizon used [ms], the receiver's counters (cumulative), and whether the tick's source was valid
STREAM_LOG = ("age_ms", "horizon_ms", "received", "accepted", "lost", "malformed", "duplicates", "reordered",
              "valid")
_BOTH_FEET = frozenset(Side)
_POSE_COMPONENTS = ("x", "y", "z", "r00", "r01", "r02", "r10", "r11", "r12", "r20", "r21", "r22")

class TeleopScenario(Scenario):
    """Hands and head from motion capture, feet in contact, CoM held (module docstring)."""

    kind = "teleop"

    # ------------------------------------------------------------------ construction
    def __init__(self, spec: ScenarioSpec, params: Section, robot: Robot, source=None):
        self._given_source = source
        super().__init__(spec, params, robot)

    def parse(self, params: Section) -> None:
        self.mocap = params.str("mocap")
        self.speed = params.float("speed", 1.0, positive=True)
        self.start = params.float("start", 0.0, min=0.0) if params.has("start") else None
        prop = params.raw("proportion", "shoulders")
        if isinstance(prop, bool) or not (prop in ("shoulders", "head") or isinstance(prop, (int, float))):
            raise params.error("proportion", f"must be 'shoulders', 'head' or a number > 0, got {prop!r}")
        if isinstance(prop, (int, float)) and not (np.isfinite(prop) and prop > 0):
            raise params.error("proportion", f"must be > 0, got {prop!r}")
        self.proportion = prop
        self.feedforward = params.bool("feedforward", True)
        self.smoothing = params.float("smoothing", 0.03, min=0.0)
        self.on_loss = params.str("on_loss", "hold", choices=["hold", "reference"])
        self.return_time = params.float("return_time", 2.0, positive=True)
        self.stale_after = params.float("stale_after", 0.2, positive=True)
        self.realtime = params.bool("realtime", True)
        self.engage_time = params.float("engage_time", 1.0, min=0.0)
        self.anchor = params.str("anchor", DEFAULT_ANCHOR, choices=list(ANCHORS))
        blend = params.vector("rest_blend", length=2) if params.has("rest_blend") else np.array(REST_BLEND)
        if not (np.all(np.isfinite(blend)) and 0.0 <= blend[0] < blend[1]):
            raise params.error("rest_blend", f"must be [r_in, r_out] with 0 <= r_in < r_out, got {list(blend)}")
        self.rest_blend = (float(blend[0]), float(blend[1]))
        self.safety = _parse_safety(params.section("safety", None), self.anchor)
        lu = params.raw("length_unit", "auto")
        if not isinstance(lu, (str, int, float)) or isinstance(lu, bool):
            raise params.error("length_unit", "use auto, m, dm, cm, mm, in, ft or metres per unit")
        self.length_unit = lu
        self.up_axis = params.str("up_axis", "auto", choices=["auto", "x", "y", "z"])
        self.segment_map_file = params.str("segment_map", "") or None
        from ..teleop.network import parse_impairment
        from ..teleop.prediction import DEFAULT_HORIZON, PREDICTORS

        net = params.raw("network", None)
        try:
            self.network = (None if net is None or (isinstance(net, str) and net.strip().lower() in ("", "none"))
                            else parse_impairment(net, where="network"))
        except ConfigError as exc:
            raise ConfigError(str(exc), file=self.spec.file or None) from None
        self.predict = params.str("predict", "none", choices=list(PREDICTORS))
        self.predict_horizon = params.float("predict_horizon", DEFAULT_HORIZON, min=0.0)
        self.predict_latency = params.float("predict_latency", 0.0, min=0.0)
        tg = params.section("targets", None)
        if tg.data:
            targets = {}
            for effector in list(tg.data):
                if effector not in DEFAULT_TARGETS:
                    raise tg.error(effector, f"unknown effector; allowed: {', '.join(DEFAULT_TARGETS)}")
                names = tg.list(effector)
                if not all(isinstance(n, str) for n in names):
                    raise tg.error(effector, "must be a list of task names")
                targets[effector] = tuple(names)
            tg.finish()
            self.targets = targets
        else:
            self.targets = dict(DEFAULT_TARGETS)
        from ..teleop.human.locomotion import LOCOMOTION_MODES

        self.locomotion = params.str("locomotion", "auto", choices=list(LOCOMOTION_MODES))
        st = params.section("stepping", None)
        self.stepping_config = None
        if self.locomotion == "stepping":
            from ..teleop.session.stepping import SteppingConfig

            kw = {k: st.float(k, positive=True) for k in ("single_support", "double_support",
                                                          "final_double_support", "preview_horizon",
                                                          "initial_shift", "apex") if st.has(k)}
            if st.has("latency"):
                kw["latency"] = st.float("latency", min=0.0)
            if st.has("catch_up"):
                kw["catch_up"] = st.int("catch_up", min=0)
            if st.bool("step_adjustment", False):
                from ..planning.step_adjustment import StepAdjustmentConfig

                self.step_adjustment = StepAdjustmentConfig.from_stepping(self.robot.profile.stepping)
            st.finish()
            self.stepping_config = SteppingConfig(**kw)
        elif st.data:
            raise params.error("stepping", "only with locomotion: stepping")
        self.relay = None
        from ..teleop import UdpPoseReceiver

        if self.locomotion == "stepping" and (self.mocap.startswith("udp://")
                                              or isinstance(self._given_source, UdpPoseReceiver)):
            raise ConfigError("locomotion 'stepping' works on recordings, not on a live stream",
                              file=self.spec.file or None, key="locomotion")
        self.source = self._open_source()

    @classmethod
    def from_source(cls, robot: Robot, mocap, *, name: str = "teleop", duration: float = 0.0,
                    control_dt: float = 1e-3, **params) -> "TeleopScenario":
        """A teleop scenario without a YAML file. `mocap`: what the `mocap` param accepts, or a
        `MocapRecording` / `UdpPoseReceiver` object; other keyword arguments are the params above."""
        from ..scene import Terrain

        spec = ScenarioSpec(name=name, kind=cls.kind, description="whole-body teleoperation", duration=duration,
                            control_dt=control_dt, terrain=Terrain(), pushes=(), file="")
        given = None if isinstance(mocap, str) else mocap
        label = mocap if isinstance(mocap, str) else (getattr(mocap, "source", "") or type(mocap).__name__)
        return cls(spec, Section({"mocap": label, **params}, None, "params"), robot, source=given)

    def _open_source(self):
        from ..teleop import MocapRecording, UdpPoseReceiver, load_recording, open_recording
        from ..teleop.registry import MOTIONS

        given = self._given_source
        if given is not None:
            if isinstance(given, MocapRecording):
                self.live = False
                return given
            if isinstance(given, UdpPoseReceiver):
                if self.network is not None:
                    raise ConfigError("a given receiver cannot be impaired: put an ImpairedRelay "
                                      "(wbcbench.teleop.network) in front of it", key="network")
                self.live = True
                return given
            raise ConfigError(f"mocap must be a MocapRecording or a UdpPoseReceiver, got {type(given).__name__}",
                              key="mocap")
        m = self.mocap
        if m.startswith("udp://"):
            host, _, port = m[len("udp://"):].rpartition(":")
            try:
                port_n = int(port)
            except ValueError:
                raise ConfigError(f"'{m}' is not udp://HOST:PORT", file=self.spec.file or None,
                                  key="mocap") from None
            self.live = True
            if self.network is None:
                return UdpPoseReceiver(port_n, host or "127.0.0.1", stale_after=self.stale_after)
            # the impaired link in front of the receiver: a relay listens where the operator sends
            from ..teleop.network import ImpairedRelay

            receiver = UdpPoseReceiver(0, "127.0.0.1", stale_after=self.stale_after)
            try:
                self.relay = ImpairedRelay(self.network, receiver.address, listen=(host or "127.0.0.1", port_n))
            except ConfigError:
                receiver.close()
                raise
            self.relay.start()
            return receiver
        self.live = False
        if m in MOTIONS:
            return open_recording(m)
        path = Path(m)
        if not path.suffix:
            raise UnknownNameError("recording", m, MOTIONS, file=self.spec.file or None, key="mocap")
        if not path.is_absolute() and self.spec.file:
            path = Path(self.spec.file).parent / path
        return load_recording(path, length_unit=self.length_unit, up_axis=self.up_axis)

    @property
    def planned_duration(self) -> float:
        if self.live:
            raise ConfigError("a live stream has no planned duration: give one (--duration or `duration:`)",
                              file=self.spec.file or None, key="duration")
        rec = self.source
        t0 = float(rec.times[0]) if self.start is None else self.start
        length = max(float(rec.times[-1]) - t0, 0.0) / self.speed
        walk = getattr(self, "walk", None)
        return length if walk is None else max(length, walk.duration)

    # ------------------------------------------------------------------ run
    def setup(self, q0: np.ndarray, com0: np.ndarray) -> None:
        super().setup(q0, com0)
        self._com_ref = PointReference(np.array(com0, dtype=float))
        self.reference_source = TeleopReferenceSource(self.robot, self.source, self.live, self._source_config())
        self.reference_source.setup(q0)
        self.walk = None
        if self.locomotion == "stepping":
            self._plan_steps(q0, com0)

    walk = None
    #: `stepping: {step_adjustment: true}`: the walk's DCM-based step adjustment (`StepAdjustmentConfig`), and its
    #: adjuster once set up
    step_adjustment = adjuster = None

    #: the walk's: the controller's task-set `step_adjustment:` settings, as a walk takes them (no key of the
    #: scenario's own: its `stepping:` section sets only whether the adjustment is on)
    adopt_step_adjustment = WalkScenario.adopt_step_adjustment
    _step_adjustment_given: frozenset = frozenset()

    def _plan_steps(self, q0: np.ndarray, com0: np.ndarray) -> None:
        """`locomotion: stepping`: the operator's steps -> the robot's walk (wbcbench/teleop/session/stepping.py),
        and the effector targets carried by its walking frame."""
        from ..errors import PlanningError
        from ..planning import Footstep, PatternGeneratorConfig, SoleRectangle, generate_walk
        from ..planning.geometry import rotation_from_yaw, yaw_of
        from ..teleop.human.locomotion import detect_steps
        from ..teleop.session.stepping import plan_operator_steps

        src = self.reference_source
        if src.walk_source is None:
            raise ConfigError("locomotion 'stepping': the recording's segments were not found",
                              file=self.spec.file or None, key="locomotion")
        rec, names, up = src.walk_source
        cal = src.retargeter.calibration or src.retargeter.calibrate()
        steps = detect_steps(rec, names, up)
        frame0 = rec.frame_at(cal.time)
        feet_suit0 = {"left": np.asarray(frame0.positions[names["LeftFoot"]], dtype=float),
                      "right": np.asarray(frame0.positions[names["RightFoot"]], dtype=float)}
        data = self.robot.model.createData()
        pin.framesForwardKinematics(self.robot.model, data, q0)
        feet0 = {}
        for s in Side:
            M = data.oMf[self.robot.sole_frame_id(s)]
            feet0[s] = Footstep.from_xyz_yaw(s, M.translation[0], M.translation[1], M.translation[2],
                                             yaw_of(M.rotation))
        sole = self.robot.profile.sole
        cfg = self.stepping_config
        t0 = float(rec.times[0]) if self.start is None else self.start
        try:
            self.step_plan = plan_operator_steps(
                steps, T_world_suit=cal.T_world_suit, proportion=cal.proportion, feet_suit0=feet_suit0,
                feet0=feet0, limits=self.robot.profile.stepping, sole=SoleRectangle(sole.length, sole.width,
                                                                                     *sole.center),
                config=cfg, time_offset=t0, speed=self.speed)
            mid = 0.5 * (feet0[Side.LEFT].p_world_sole + feet0[Side.RIGHT].p_world_sole)
            pg = PatternGeneratorConfig(com_height=float(com0[2] - mid[2]), dt=self.spec.control_dt,
                                        swing_apex_height=cfg.apex, preview_horizon=cfg.preview_horizon,
                                        initial_shift=cfg.initial_shift, final_shift=min(0.8, cfg.final_double_support))
            self.walk = generate_walk(self.step_plan.plan, pg, p_world_com_init=com0)
        except PlanningError as exc:
            raise ConfigError(f"locomotion 'stepping': {exc}", file=self.spec.file or None,
                              key="locomotion") from None
        self._R_base0 = pin.Quaternion(q0[6], *q0[3:6]).toRotationMatrix()
        self._rotation_from_yaw = rotation_from_yaw
        self._use_walk(self.walk)
        src.carry(self._carry)
        self.adjuster = None
        if self.step_adjustment is not None:
            from ..estimation.feet import FeetSensing
            from ..planning.step_adjustment import StepAdjuster

            sep = float(np.linalg.norm(feet0[Side.LEFT].p_world_sole[:2] - feet0[Side.RIGHT].p_world_sole[:2]))
            self.adjuster = StepAdjuster(self.walk, self.step_adjustment, pg, sep)
            self._data = self.robot.model.createData()
            self._feet = FeetSensing(self.robot)

    def _use_walk(self, w) -> None:
        """The references' table and the walking frame of walk `w` (the plan, or a step adjustment's re-plan)."""
        from ..planning.geometry import yaw_of

        self.walk = w
        self._walk_table = _WalkTable(w)
        # the walking frame per tick: the planned CoM's horizontal position (the pelvis goes with it; the feet's
        # midpoint would jump forward with each swing) and the feet's mean heading, their rates
        fl, fr = w.feet[Side.LEFT], w.feet[Side.RIGHT]
        horizontal = np.array([1.0, 1.0, 0.0])
        self._frame_p = w.p_world_com * horizontal
        self._frame_v = w.v_world_com * horizontal
        self._frame_a = w.a_world_com * horizontal
        yaw = 0.5 * (np.unwrap([yaw_of(R) for R in fl.R_world_sole]) + np.unwrap([yaw_of(R) for R in fr.R_world_sole]))
        self._frame_yaw = yaw - yaw[0]
        self._frame_rate = np.gradient(self._frame_yaw, w.dt) if len(yaw) > 1 else np.zeros(len(yaw))

    def _walk_tick(self, t: float) -> int:
        return min(int(round(t / self.walk.dt)), self.walk.n_ticks - 1)

    def _carry(self, t: float, targets: dict) -> dict:
        """Effector targets (standing frame) -> moved with the walking frame at t: p' = m(t) + R(t) (p - m(0)),
        R' = R(t) R, velocities and accelerations turned, the frame's own added (its rotation's centripetal and
        Euler terms left out: the robot turns slowly)."""
        k = self._walk_tick(t)
        m0, m = self._frame_p[0], self._frame_p[k]
        Rz = self._rotation_from_yaw(float(self._frame_yaw[k]))
        w = np.array([0.0, 0.0, float(self._frame_rate[k])])
        out = {}
        for e, (M, vel, acc) in targets.items():
            r = Rz @ (M.translation - m0)
            v = np.concatenate([Rz @ vel[:3] + self._frame_v[k] + np.cross(w, r), Rz @ vel[3:] + w])
            a = np.concatenate([Rz @ acc[:3] + self._frame_a[k], Rz @ acc[3:]])
            out[e] = (pin.SE3(Rz @ M.rotation, m + r), v, a)
        return out

    def observe(self, t: float, meas) -> None:
        """The tick's measurement, before `references`: the command filter's body spheres follow the measured
        posture."""
        self.reference_source.follow(t, meas.q)
        if self.adjuster is not None:  # the walk's own step adjustment (the same attributes: walk, adjuster, ...)
            walk = self.walk
            WalkScenario.observe(self, t, meas)
            if self.walk is not walk:
                self._use_walk(self.walk)

    def references(self, t: float) -> References:
        """Both feet down, the CoM held, the operator's hands and head as the named frame tasks' references
        (`TeleopReferenceSource`, wbcbench/teleop/source.py)."""
        if self.walk is None:
            return References.planned(t, _BOTH_FEET, self._com_ref, None, {}, self.reference_source.targets(t))
        k = self._walk_tick(t)
        ref = self._walk_table._make(t, k)
        targets = dict(self.reference_source.targets(t))
        targets["waist"] = PoseReference(np.zeros(3), self._rotation_from_yaw(float(self._frame_yaw[k]))
                                         @ self._R_base0)
        return References.planned(t, ref.contacts, ref.com, ref.zmp, ref.feet, targets, ref.lift_off,
                                  ref.swing_pitch)

    @property
    def target_names(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(n for names in self.targets.values() for n in names))

    def _source_config(self) -> TeleopSourceConfig:
        dt = self.spec.control_dt
        duration = self.spec.duration if self.spec.duration > 0 else (0.0 if self.live else self.planned_duration)
        return TeleopSourceConfig(speed=self.speed, start=self.start, proportion=self.proportion,
                                  feedforward=self.feedforward, smoothing=self.smoothing, on_loss=self.on_loss,
                                  return_time=self.return_time, stale_after=self.stale_after, realtime=self.realtime,
                                  engage_time=self.engage_time, anchor=self.anchor, rest_blend=self.rest_blend,
                                  targets=dict(self.targets), dt=dt, duration=duration, safety=self.safety,
                                  segment_map=self._segment_map(), network=self.network, predict=self.predict,
                                  predict_horizon=self.predict_horizon, predict_latency=self.predict_latency,
                                  locomotion=self.locomotion)

    def _segment_map(self) -> dict | None:
        """The `segment_map` file's mapping (checked against the recording's segments), or None."""
        if self.segment_map_file is None:
            return None
        from ..teleop.skeleton_map import load_segment_map

        path = Path(self.segment_map_file)
        if not path.is_absolute() and self.spec.file:
            path = Path(self.spec.file).parent / path
        return load_segment_map(path, getattr(self.source, "segments", None)).names

    def log_channels(self) -> dict:
        """Per tick, the command filter's interventions (1 where one happened; wbcbench/teleop/safety.py)."""
        from ..teleop.safety import FILTER_KINDS

        out = {"teleop_filter": list(FILTER_KINDS)}
        if self.live or self.network is not None:
            out["teleop_stream"] = list(STREAM_LOG)
        if self.network is not None and not self.live:
            out["teleop_truth"] = [f"{h}.{c}" for h in HANDS for c in _POSE_COMPONENTS]
        return out

    def log_values(self) -> list:
        src = self.reference_source
        out = [src.command_filter.flags]
        if self.live or self.network is not None:
            receiver = self.source if self.live else src.link.receiver
            st = receiver.stats
            out.append(np.array([1e3 * src.stream_age, 1e3 * src.stream_horizon, st.received, st.accepted, st.lost,
                                 st.malformed, st.duplicates, st.reordered, float(src.record_valid[-1])]))
        if self.network is not None and not self.live:
            out.append(src.truth)
        return out

    def __getattr__(self, name: str):
        # the reference source's state (trajectory, poses, health counters) read through the scenario
        if name != "reference_source" and "reference_source" in self.__dict__:
            return getattr(self.reference_source, name)
        raise AttributeError(name)

    # ------------------------------------------------------------------ metrics
    def metrics(self, log: dict) -> dict:
        """Table II statistics from the log (`wbcbench.teleop.metrics`, the same function `wbcbench report`
        uses) and the source's health."""
        from ..teleop.metrics import teleop_errors_from_log, teleop_metrics_from_log

        m = min(len(log["t"]), len(self.record_t))
        errors = teleop_errors_from_log(log, self.robot)
        errors["t"] = np.asarray(self.record_t[:m])
        self.hand_error_samples = errors
        out = teleop_metrics_from_log(log, self.robot, errors)
        valid = np.array(self.record_valid[:m])
        losses = list(self.loss_durations)
        if self._loss_start is not None and self._valid_prev is False:
            losses.append(self.record_t[m - 1] - self._loss_start if m else 0.0)
        teleop = {"source": "udp" if self.live else "recording", "mocap": self.mocap, "speed": self.speed,
                  "valid_ticks": int(valid.sum()), "invalid_ticks": int((~valid).sum()),
                  "loss_events": self.loss_events, "invalid_time_s": float((~valid).sum() * self.spec.control_dt),
                  "longest_invalid_s": float(max(losses, default=0.0)), "on_loss": self.on_loss,
                  "clamped_ticks": dict(self.clamped_ticks)}
        src = self.reference_source
        if src.streamed:
            stream_src = src.link.receiver if src.link is not None else self.source
            st = stream_src.stats
            teleop["stream"] = {"received": st.received, "accepted": st.accepted, "lost": st.lost,
                                "malformed": st.malformed, "duplicates": st.duplicates, "reordered": st.reordered,
                                "restarts": st.restarts, "last_error": st.last_error,
                                "status_at_end": stream_src.status().value}
            link = src.link.link if src.link is not None else (self.relay.link if self.relay is not None else None)
            if self.network is not None:
                teleop["network"] = {"spec": self.network.describe(),
                                     "path": "simulated" if src.link is not None else "relay",
                                     "link": link.stats.as_dict() if link is not None else None}
            teleop["watchdog"] = src.watchdog   # None, or why the robot was held (the stream switched skeleton)
            horizons = log.get("teleop_stream.horizon_ms")
            teleop["prediction"] = {"method": self.predict, "max_horizon_s": self.predict_horizon,
                                    "horizon_ms": stats(np.asarray(horizons)) if horizons is not None else None}
        if self.walk is not None:
            teleop["stepping"] = self._stepping_metrics(log)
        teleop["filter"] = self.reference_source.command_filter.summary()
        teleop["skeleton"] = self.reference_source.skeleton_summary()
        out["teleop"] = teleop
        return out


    #: after a robot touch-down, when its sole's measured placement is read [s] (inside the double support)
    TOUCH_DOWN_SETTLE = 0.1

    def _stepping_metrics(self, log: dict) -> dict:
        """`locomotion: stepping`: the robot's steps against the operator's. Per operator step, the robot's sole
        (x, y) measured `TOUCH_DOWN_SETTLE` after the planned touch-down of the robot step that answers it (from
        the log's configuration), its distance to the operator's scaled placement (`placement_error_m`) and to
        the planned (clamped) one (`tracking_error_m`); steps whose touch-down the run did not reach are left
        out (`steps_reached`)."""
        from ..recorder import channel

        sp, plan, dt = self.step_plan, self.step_plan.plan, self.walk.dt
        q = channel(log, "q")
        model, data = self.robot.model, self.robot.model.createData()
        rows = []
        for pl in sp.placements:
            i = pl["robot_step"]
            k = int(round((plan.touch_down_time(i) + self.TOUCH_DOWN_SETTLE) / dt))
            row = {**pl, "robot_touch_down_s": float(plan.touch_down_time(i))}
            if k < len(q):
                pin.framesForwardKinematics(model, data, q[k])
                p = data.oMf[self.robot.sole_frame_id(Side(pl["side"]))].translation
                row["measured"] = [float(p[0]), float(p[1])]
                row["placement_error_m"] = float(np.linalg.norm(p[:2] - np.array(pl["target"][:2])))
                row["tracking_error_m"] = float(np.linalg.norm(p[:2] - np.array(pl["planned"][:2])))
            rows.append(row)
        reached = [r for r in rows if "measured" in r]
        t_end = float(log["t"][-1]) if len(log["t"]) else 0.0
        return {"operator_steps": len(sp.placements), "robot_steps": plan.n_steps,
                "robot_steps_taken": sum(plan.touch_down_time(i) + self.TOUCH_DOWN_SETTLE <= t_end
                                         for i in range(plan.n_steps)),
                "extra_steps": sp.extra_steps, "steps_reached": len(reached),
                "latency_s": sp.latency, "look_ahead_s": sp.look_ahead,
                "step_adjustments": None if self.adjuster is None else self.adjuster.count,
                "placement_error_m": stats(np.array([r["placement_error_m"] for r in reached])),
                "tracking_error_m": stats(np.array([r["tracking_error_m"] for r in reached])),
                "clamp_m": stats(np.array([r["clamp_m"] for r in rows])),
                "steps": rows}


def _parse_safety(sec, anchor: str):
    """The `safety` params (wbcbench/teleop/safety.py): any SafetyConfig field; `body` defaults to off with the
    paper's absolute anchor (its references inside the body are what the repulsors are studied on)."""
    from dataclasses import fields

    from ..teleop.safety import SafetyConfig

    values = {}
    for f in fields(SafetyConfig):
        if not sec.has(f.name):
            continue
        if f.type in ("bool", bool):
            values[f.name] = sec.bool(f.name)
        elif f.name == "hand_angular_speed" and isinstance(sec.raw(f.name), str):
            values[f.name] = sec.str(f.name, choices=("wrist",))
        else:
            values[f.name] = (sec.float(f.name, min=0.0) if f.name in ("body_margin", "body_period")
                              else sec.float(f.name, positive=True))
    values.setdefault("body", anchor != "absolute")
    sec.finish()
    return SafetyConfig(**values)
