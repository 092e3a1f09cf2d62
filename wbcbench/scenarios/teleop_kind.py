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
    Live streams never feed forward: their references are the latest frame through a first-order low-pass
    (`smoothing` [s], default 0.03) so that 50-60 Hz steps do not reach the 8000 s^-2 hand tasks as jumps.
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
  targets: {effector: [task names]} (default left_hand -> [left_hand], right_hand -> [right_hand],
    head -> [head, head_pitch, head_yaw]).

Metrics (summary.json `metrics`), from the log's ground-truth configuration against the reference the
controller was given at each tick: `hand_position_error_m` and `hand_rotation_error` (||I - R_ref R^T||_F,
paper Table II), each {mean, std, min, max} over both hands and all ticks, the same per hand
(`hand_errors`); the same restricted to the ticks whose reference lies outside the robot's body
(`hand_position_error_outside_body_m`, `hand_rotation_error_outside_body`: the reference's protected point,
the gripper centre of the profile's `repulsors`, farther than r_rep + r_frame from every repulsion point at the
robot's configuration of that tick) and the fraction inside (`hand_reference_inside_body_fraction`): a
reference inside the hips cannot be tracked without interpenetration, whatever the controller;
`head_position_error_m`; and `teleop` (invalid ticks, loss events and their duration, clamped ticks per
effector, the live stream's receiver counters).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..config import Section
from ..errors import ConfigError, UnknownNameError
from ..robots import Robot, Side
from ..types import PointReference, PoseReference, References
from .base import Scenario, ScenarioSpec, register_kind

DEFAULT_TARGETS = {"left_hand": ("left_hand",), "right_hand": ("right_hand",),
                   "head": ("head", "head_pitch", "head_yaw")}
HANDS = ("left_hand", "right_hand")
#: `anchor` values (module docstring).
ANCHORS = ("absolute", "offset", "rest")
DEFAULT_ANCHOR = "rest"
#: default `rest_blend` [m]: the `rest` anchor's offset is whole within r_in of the calibration position, none
#: beyond r_out.
REST_BLEND = (0.10, 0.50)


def stats(x: np.ndarray) -> dict:
    """{mean, std, min, max} of a 1-D array (None values when empty)."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"mean": None, "std": None, "min": None, "max": None}
    return {"mean": float(x.mean()), "std": float(x.std()), "min": float(x.min()), "max": float(x.max())}


def rotation_error(R_ref: np.ndarray, R: np.ndarray) -> np.ndarray:
    """||I - R_ref R^-1||_F (paper 004 Table II, after Huynh 2009), in [0, 2 sqrt(2)]; batched over (..., 3, 3)."""
    E = np.eye(3) - R_ref @ np.swapaxes(R, -1, -2)
    return np.sqrt((E * E).sum(axis=(-2, -1)))


def _min_jerk(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


@dataclass
class _Trajectory:
    """Effector references precomputed from a recording, one row per control tick (index round(t / dt)).

    position (N, 3) [m], rotation (N, 3, 3), velocity / acceleration (N, 6) [m/s, rad/s; m/s^2, rad/s^2] in world
    axes, per effector; valid and clamped (N,) flags. Ticks past the end hold the last row."""

    position: dict
    rotation: dict
    velocity: dict
    acceleration: dict
    valid: np.ndarray
    clamped: dict

    @property
    def n(self) -> int:
        return len(self.valid)


@register_kind
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
            return UdpPoseReceiver(port_n, host or "127.0.0.1", stale_after=self.stale_after)
        self.live = False
        if m in MOTIONS:
            return open_recording(m)
        path = Path(m)
        if not path.suffix:
            raise UnknownNameError("recording", m, MOTIONS, file=self.spec.file or None, key="mocap")
        if not path.is_absolute() and self.spec.file:
            path = Path(self.spec.file).parent / path
        return load_recording(path)

    @property
    def planned_duration(self) -> float:
        if self.live:
            raise ConfigError("a live stream has no planned duration: give one (--duration or `duration:`)",
                              file=self.spec.file or None, key="duration")
        rec = self.source
        t0 = float(rec.times[0]) if self.start is None else self.start
        return max(float(rec.times[-1]) - t0, 0.0) / self.speed

    # ------------------------------------------------------------------ run
    def setup(self, q0: np.ndarray, com0: np.ndarray) -> None:
        from ..teleop import Retargeter

        super().setup(q0, com0)
        self._com_ref = PointReference(np.array(com0, dtype=float))
        self.retargeter = Retargeter(self.robot, self.source, proportion=self.proportion)
        self.reference_poses = {k: pin.SE3(v) for k, v in self.retargeter.reference_poses.items()}
        model = self.robot.model
        data = model.createData()
        pin.framesForwardKinematics(model, data, q0)
        frames = {"left_hand": self.robot.profile.hands[Side.LEFT],
                  "right_hand": self.robot.profile.hands[Side.RIGHT], "head": self.robot.profile.head_frame}
        self.initial_poses = {k: pin.SE3(data.oMf[model.getFrameId(f)]) for k, f in frames.items()}
        self.offsets = {k: np.zeros(3) for k in DEFAULT_TARGETS}
        self.calibration_positions: dict[str, np.ndarray] = {}
        if self.anchor != "absolute" and not self.live:
            cal = self.retargeter.sample(float(self.source.times[0]) if self.start is None else self.start)
            self._set_anchor(cal.references)
        self.trajectory = None if self.live else self._precompute()
        self._held = {k: (pin.SE3(v), np.zeros(6), np.zeros(6)) for k, v in self.reference_poses.items()}
        self._filtered: dict[str, pin.SE3] = {}
        self._live_offset_set = False
        self._valid_prev = None
        self._loss_start = None
        self._wall0 = None
        self.record_t: list[float] = []
        self.record_valid: list[bool] = []
        self.record_pose: dict[str, list[np.ndarray]] = {k: [] for k in DEFAULT_TARGETS}
        self.clamped_ticks = {k: 0 for k in DEFAULT_TARGETS}
        self.loss_events = 0
        self.loss_durations: list[float] = []

    def _set_anchor(self, references: dict) -> None:
        """Calibration of the `offset` / `rest` anchors on one retargeted frame (the operator at rest)."""
        self.calibration_positions = {k: np.array(M.translation) for k, M in references.items()}
        self.offsets = {k: self.reference_poses[k].translation - M.translation for k, M in references.items()}

    def _anchored(self, effector: str, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Effector positions (N, 3) of the absolute retargeting -> the anchor's positions, and (N,) flags of the
        rows moved back into the reach shell (non-absolute anchors only; the retargeter clamped the absolute
        ones already)."""
        P = np.atleast_2d(np.asarray(P, dtype=float))
        if self.anchor == "absolute" or effector not in self.calibration_positions:
            return P, np.zeros(len(P), dtype=bool)
        off = self.offsets[effector]
        if self.anchor == "offset":
            out = P + off
        else:  # rest: the offset near the calibration position, none beyond rest_blend[1]
            r_in, r_out = self.rest_blend
            dist = np.linalg.norm(P - self.calibration_positions[effector], axis=1)
            u = np.clip((dist - r_in) / (r_out - r_in), 0.0, 1.0)
            w = 1.0 - (10 * u**3 - 15 * u**4 + 6 * u**5)
            out = P + w[:, None] * off
        shell = self.retargeter.workspaces.get(effector) if effector != "head" else None
        moved = np.zeros(len(out), dtype=bool)
        if shell is not None:
            for i, p in enumerate(out):
                out[i], moved[i] = shell.clamp(p)
        return out, moved

    def _precompute(self) -> _Trajectory:
        """Retarget every recorded frame once, fit C2 splines (scipy CubicSpline for positions, RotationSpline
        for orientations) over source time, and evaluate them at every control tick of the run."""
        from scipy.interpolate import CubicSpline
        from scipy.spatial.transform import Rotation, RotationSpline

        rec = self.source
        times = np.asarray(rec.times, dtype=float)
        samples = [self.retargeter.sample(float(t)) for t in times]
        t0 = float(times[0]) if self.start is None else self.start
        dt = self.spec.control_dt
        duration = self.spec.duration if self.spec.duration > 0 else self.planned_duration
        n = int(round(duration / dt)) + 2
        tau = t0 + np.arange(n) * dt * self.speed
        inside = (tau >= times[0]) & (tau <= times[-1])
        tc = np.clip(tau, times[0], times[-1])
        k = np.clip(np.searchsorted(times, tc), 0, len(times) - 1)
        frame_valid = np.array([s.valid for s in samples])
        ff = self.speed if self.feedforward else 0.0
        out = {"position": {}, "rotation": {}, "velocity": {}, "acceleration": {}, "clamped": {}}
        for e in DEFAULT_TARGETS:
            P, moved = self._anchored(e, np.array([s.references[e].translation for s in samples]))
            R = Rotation.from_matrix(np.array([s.references[e].rotation for s in samples]))
            if len(times) >= 2:
                ps, rs = CubicSpline(times, P, bc_type="clamped"), RotationSpline(times, R)
                pos, rot = ps(tc), rs(tc).as_matrix()
                # RotationSpline's rates are in the rotating (body) frame; the frame tasks want world axes:
                # omega_w = R omega_b and, since omega_w x omega_w = 0, omega_dot_w = R omega_dot_b
                w_world = np.einsum("nij,nj->ni", rot, rs(tc, 1))
                dw_world = np.einsum("nij,nj->ni", rot, rs(tc, 2))
                vel = np.hstack([ps(tc, 1), w_world]) * ff
                acc = np.hstack([ps(tc, 2), dw_world]) * ff * ff
            else:
                pos, rot = np.repeat(P, n, axis=0), np.repeat(R.as_matrix(), n, axis=0)
                vel = acc = np.zeros((n, 6))
            vel[~inside] = 0.0
            acc[~inside] = 0.0
            out["position"][e], out["rotation"][e] = pos, rot
            out["velocity"][e], out["acceleration"][e] = vel, acc
            out["clamped"][e] = (np.array([s.clamped[e] for s in samples]) | moved)[k]
        return _Trajectory(**out, valid=inside & frame_valid[k])

    def _recorded_targets(self, t: float) -> tuple[dict, bool, dict]:
        tr = self.trajectory
        k = min(int(round(t / self.spec.control_dt)), tr.n - 1)
        out = {e: (pin.SE3(tr.rotation[e][k], tr.position[e][k]), tr.velocity[e][k].copy(),
                   tr.acceleration[e][k].copy()) for e in DEFAULT_TARGETS}
        return out, bool(tr.valid[k]), {e: bool(tr.clamped[e][k]) for e in DEFAULT_TARGETS}

    def _live_targets(self, t: float) -> tuple[dict, bool, dict]:
        if self.realtime:
            if self._wall0 is None:
                self._wall0 = time.monotonic() - t
            ahead = t - (time.monotonic() - self._wall0)
            if ahead > 0:
                time.sleep(ahead)
        sample = self.retargeter.sample(t)
        if self.anchor != "absolute" and sample.valid and not self._live_offset_set:
            self._set_anchor(sample.references)
            self._live_offset_set = True
        anchored = {k: self._anchored(k, M.translation) for k, M in sample.references.items()}
        clamped = {k: bool(c or anchored[k][1][0]) for k, c in sample.clamped.items()}
        sample = sample._replace(references={k: pin.SE3(M.rotation, anchored[k][0][0])
                                             for k, M in sample.references.items()}, clamped=clamped)
        alpha = 1.0 if self.smoothing <= 0 else 1.0 - np.exp(-self.spec.control_dt / self.smoothing)
        out = {}
        for e, M in sample.references.items():
            prev = self._filtered.get(e)
            if prev is None or not sample.valid:
                F = pin.SE3(M)
            else:
                F = pin.SE3(prev.rotation @ pin.exp3(alpha * pin.log3(prev.rotation.T @ M.rotation)),
                            prev.translation + alpha * (M.translation - prev.translation))
            if sample.valid:
                self._filtered[e] = F
            out[e] = (F, np.zeros(6), np.zeros(6))
        return out, bool(sample.valid), dict(sample.clamped)

    def references(self, t: float) -> References:
        targets, valid, clamped = (self._live_targets(t) if self.live else self._recorded_targets(t))
        dt = self.spec.control_dt
        if valid:
            if self._valid_prev is False and self._loss_start is not None:
                self.loss_durations.append(t - self._loss_start)
                self._loss_start = None
            self._held = {k: (pin.SE3(v[0]), np.zeros(6), np.zeros(6)) for k, v in targets.items()}
            self._hold_from = None
        else:
            if self._valid_prev is not False:
                # a loss starts (before any valid frame this is the start of the run)
                if self._valid_prev is True:
                    self.loss_events += 1
                self._loss_start = t
                self._hold_from = {k: pin.SE3(v[0]) for k, v in self._held.items()}
            targets = self._safe_targets(t)
        self._valid_prev = valid
        if t < self.engage_time:
            targets = self._engage(t, targets)
        for k, c in clamped.items():
            self.clamped_ticks[k] += int(c)
        self.record_t.append(t)
        self.record_valid.append(valid)
        for k in DEFAULT_TARGETS:
            M = targets[k][0]
            self.record_pose[k].append(np.concatenate([M.translation, M.rotation.reshape(-1)]))
        named = {}
        for effector, tasks in self.targets.items():
            M, vel, acc = targets[effector]
            ref = PoseReference(M.translation, M.rotation, vel, acc)
            for task in tasks:
                named[task] = ref
        return References(t=t, contacts=frozenset(Side), com=self._com_ref, targets=named)

    def _engage(self, t: float, targets: dict) -> dict:
        """Min-jerk blend from the robot's initial effector poses into `targets` (see `engage_time`)."""
        T = self.engage_time
        u = t / T
        s = _min_jerk(u)
        ds = (30 * u**2 - 60 * u**3 + 30 * u**4) / T
        out = {}
        for k, (M, vel, acc) in targets.items():
            M0 = self.initial_poses[k]
            dp = M.translation - M0.translation
            dr = pin.log3(M.rotation @ M0.rotation.T)  # world-axes rotation from M0 to M
            R = pin.exp3(s * dr) @ M0.rotation
            v = s * vel
            v[:3] += ds * dp
            v[3:] += ds * dr
            out[k] = (pin.SE3(R, M0.translation + s * dp), v, s * acc)
        return out

    def _safe_targets(self, t: float) -> dict:
        if self.on_loss == "hold":
            return self._held
        s = _min_jerk((t - self._loss_start) / self.return_time)
        out = {}
        for k, M0 in self._hold_from.items():
            M1 = self.reference_poses[k]
            R = M0.rotation @ pin.exp3(s * pin.log3(M0.rotation.T @ M1.rotation))
            out[k] = (pin.SE3(R, M0.translation + s * (M1.translation - M0.translation)), np.zeros(6), np.zeros(6))
        return out

    # ------------------------------------------------------------------ metrics
    def metrics(self, log: dict) -> dict:
        n = len(log["t"])
        robot = self.robot
        model = robot.model
        data = model.createData()
        names = ["x", "y", "z", "qx", "qy", "qz", "qw"] + robot.joint_names
        Q = np.column_stack([log[f"q.{c}"] for c in names])
        frames = {"left_hand": robot.profile.hands[Side.LEFT], "right_hand": robot.profile.hands[Side.RIGHT],
                  "head": robot.profile.head_frame}
        fids = {k: model.getFrameId(f) for k, f in frames.items()}
        sides = {"left_hand": Side.LEFT, "right_hand": Side.RIGHT}
        reps = {h: robot.profile.repulsors.get(s) for h, s in sides.items()}
        rep_points = {h: [(model.getFrameId(p.frame), np.array(p.offset), p.radius + r.radius) for p in r.points]
                      for h, r in reps.items() if r is not None}
        m = min(n, len(self.record_t))
        ref = {k: np.array(v[:m]) for k, v in self.record_pose.items()}
        pos = {k: np.empty((m, 3)) for k in frames}
        rot = {k: np.empty((m, 3, 3)) for k in frames}
        inside = {h: np.zeros(m, dtype=bool) for h in HANDS}
        for i in range(m):
            pin.framesForwardKinematics(model, data, Q[i])
            for k, fid in fids.items():
                M = data.oMf[fid]
                pos[k][i] = M.translation
                rot[k][i] = M.rotation
            for h, points in rep_points.items():
                R_ref = ref[h][i, 3:].reshape(3, 3)
                x = ref[h][i, :3] + R_ref @ np.asarray(reps[h].offset)
                inside[h][i] = any(np.linalg.norm(x - data.oMf[fid].act(off)) < a for fid, off, a in points)
        e_pos = {k: np.linalg.norm(ref[k][:, :3] - pos[k], axis=1) for k in frames}
        e_rot = {k: rotation_error(ref[k][:, 3:].reshape(-1, 3, 3), rot[k]) for k in frames}
        self.hand_error_samples = {"position": np.stack([e_pos[h] for h in HANDS]),
                                   "rotation": np.stack([e_rot[h] for h in HANDS]),
                                   "reference_inside_body": np.stack([inside[h] for h in HANDS]),
                                   "head_position": e_pos["head"], "t": np.asarray(self.record_t[:m])}
        outside = np.concatenate([~inside[h] for h in HANDS])
        all_pos = np.concatenate([e_pos[h] for h in HANDS])
        all_rot = np.concatenate([e_rot[h] for h in HANDS])
        out = {
            "hand_position_error_m": stats(all_pos),
            "hand_rotation_error": stats(all_rot),
            "hand_errors": {h: {"position_m": stats(e_pos[h]), "rotation": stats(e_rot[h])} for h in HANDS},
            "hand_position_error_outside_body_m": stats(all_pos[outside]),
            "hand_rotation_error_outside_body": stats(all_rot[outside]),
            "hand_reference_inside_body_fraction": float(1.0 - outside.mean()) if outside.size else None,
            "head_position_error_m": stats(e_pos["head"]),
        }
        valid = np.array(self.record_valid[:m])
        losses = list(self.loss_durations)
        if self._loss_start is not None and self._valid_prev is False:
            losses.append(self.record_t[m - 1] - self._loss_start if m else 0.0)
        teleop = {"source": "udp" if self.live else "recording", "mocap": self.mocap, "speed": self.speed,
                  "valid_ticks": int(valid.sum()), "invalid_ticks": int((~valid).sum()),
                  "loss_events": self.loss_events, "invalid_time_s": float((~valid).sum() * self.spec.control_dt),
                  "longest_invalid_s": float(max(losses, default=0.0)), "on_loss": self.on_loss,
                  "clamped_ticks": dict(self.clamped_ticks)}
        if self.live:
            st = self.source.stats
            teleop["stream"] = {"received": st.received, "accepted": st.accepted, "lost": st.lost,
                                "malformed": st.malformed, "duplicates": st.duplicates, "reordered": st.reordered,
                                "restarts": st.restarts, "last_error": st.last_error,
                                "status_at_end": self.source.status().value}
        out["teleop"] = teleop
        return out
