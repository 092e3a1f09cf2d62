"""The teleoperation reference source: operator poses (a recording or a live stream) -> the references of the
controller's named frame tasks at time t, as a planner gives a walk's (the `teleop` scenario kind calls it).

What it does each tick (the `teleop` kind's params; see wbcbench/scenarios/teleop_kind.py for their meaning):
retargeting (`Retargeter`), the anchor (absolute, offset, rest), C2 splines over a recording's frames with their
velocities and accelerations as feed-forward (or a first-order filter on a live stream's latest frame), pacing
to the wall clock for live streams, the signal-loss policy (hold, or return to the reference posture), the
engagement blend from the robot's own poses, and the bookkeeping of valid / invalid ticks, losses and clamped
effectors (`record_*`, `loss_events`, `clamped_ticks`).

Streams (a live receiver, or a recording through the simulated impaired link of wbcbench/teleop/link/network.py,
`network`): the newest frame can be extrapolated over its age (`predict`: velocity or spline,
wbcbench/teleop/link/prediction.py, capped at `predict_horizon`) before the filter. Its age is exact on the simulated
link (one clock); on a live stream, with no clock shared with the sender, it is the time since the frame's
sending as far as the receiver can tell (its delay beyond the fastest delivery seen, plus the time since it
arrived) plus `predict_latency`, the fixed one-way latency the receiver cannot observe (e.g. half the round trip).
Each tick's age and horizon are kept (`stream_age`, `stream_horizon`) for the log; on the simulated link, so is
the undelayed reference of the hands (`truth`: the recording's spline at t, what the robot should be doing now).

A recording replayed directly has its common tick (a valid row the command filter has nothing to do on) served from
the precomputed rows stacked per tick, screened by the filter in one compiled call, without pose objects
(`_row_targets`); everything else takes the general path, with the same results bit for bit
(tests/teleop/test_source_rows.py).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ...errors import ConfigError
from ...side import Side
from ...types import PoseReference
from ..human.locomotion import fix_feet
from ..io.recording import MocapRecording
from ..link.network import ImpairedReplay, NetworkImpairment
from ..link.prediction import DEFAULT_HORIZON, PosePredictor
from ..safety.command_filter import CommandFilter, SafetyConfig

__all__ = ["ANCHORS", "DEFAULT_ANCHOR", "DEFAULT_TARGETS", "HANDS", "REST_BLEND", "TeleopReferenceSource",
           "TeleopSourceConfig", "rotation_error", "stats"]

DEFAULT_TARGETS = {"left_hand": ("left_hand",), "right_hand": ("right_hand",),
                   "head": ("head", "head_pitch", "head_yaw")}
HANDS = ("left_hand", "right_hand")
#: `anchor` values.
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


@dataclass
class _Rows:
    """A recording's per-tick references stacked for the common tick (`TeleopReferenceSource._row_targets`): the
    effectors in DEFAULT_TARGETS order, P (n, 3, 3), R (n, 3, 3, 3), V, A (n, 3, 6) (the trajectory's dicts are
    views of them), and the same for the ticks k of the engagement blend (k dt < engage_time, at t = k dt, where the
    row is valid: `engaged_ok`), computed once with the blend's own code."""

    P: np.ndarray
    R: np.ndarray
    V: np.ndarray
    A: np.ndarray
    valid: list  # (n,) bools (Python's: read one per tick)
    clamped: np.ndarray  # (n, 3) bool
    any_clamped: list  # (n,) bools
    engaged: tuple = ()
    engaged_ok: list = field(default_factory=list)



@dataclass(frozen=True)
class TeleopSourceConfig:
    """The parsed `teleop` params the source needs, the control period `dt` [s] and the run's `duration` [s]
    (recordings: the ticks precomputed; 0 for a live stream)."""

    speed: float = 1.0
    start: float | None = None
    proportion: object = "shoulders"
    feedforward: bool = True
    smoothing: float = 0.03
    on_loss: str = "hold"
    return_time: float = 2.0
    stale_after: float = 0.2
    realtime: bool = True
    engage_time: float = 1.0
    anchor: str = DEFAULT_ANCHOR
    rest_blend: tuple[float, float] = REST_BLEND
    targets: dict = field(default_factory=lambda: dict(DEFAULT_TARGETS))
    dt: float = 1e-3
    duration: float = 0.0
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    segment_map: dict | None = None
    network: NetworkImpairment | None = None
    predict: str = "none"
    predict_horizon: float = DEFAULT_HORIZON
    predict_latency: float = 0.0
    locomotion: str = "auto"
    #: streams: the skeleton watchdog's relative tolerance on a bone's length (`Retargeter.watch_skeleton`; 0: off)
    skeleton_tolerance: float = 0.15


class TeleopReferenceSource:
    """Operator poses -> named frame-task references (module docstring). `source`: a `MocapRecording` or a
    `UdpPoseReceiver` (`live`)."""

    def __init__(self, robot, source, live: bool, config: TeleopSourceConfig):
        self.robot = robot
        self.source = source
        self.live = live
        self.config = config
        for name in ("speed", "start", "proportion", "feedforward", "smoothing", "on_loss", "return_time",
                     "realtime", "engage_time", "anchor", "rest_blend", "dt", "duration"):
            setattr(self, name, getattr(config, name))
        self.task_names = dict(config.targets)  # effector -> the frame tasks it feeds

    def setup(self, q0: np.ndarray) -> None:
        """Retarget, calibrate the anchor and precompute a recording's references, at the robot's start q0."""
        from ..human.retargeting import Retargeter

        self.operator_motion = None
        self.walk_source = None
        if not self.live and isinstance(self.source, MocapRecording):
            self.source, self.operator_motion = self._fixed_feet(self.source)
        self.retargeter = Retargeter(self.robot, self.source, proportion=self.proportion,
                                     segment_map=self.config.segment_map)
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
        self._rows = None
        self.trajectory = None if self.live else self._precompute()
        cfg = self.config
        # a recording through the simulated impaired link: references from what arrived; the trajectory above
        # stays as the undelayed truth the hand errors are also measured against
        self.link = (ImpairedReplay(self.source, cfg.network, speed=self.speed, start=self.start,
                                    stale_after=cfg.stale_after) if cfg.network is not None and not self.live
                     else None)
        self.streamed = self.live or self.link is not None
        self.predictor = (PosePredictor(cfg.predict, cfg.predict_horizon, max_gap=cfg.stale_after)
                          if self.streamed else None)
        if self.streamed:  # a stream may switch skeleton mid-run: hold the robot then, and say why
            self.retargeter.watch_skeleton(cfg.skeleton_tolerance)
        self._filtered_rate: dict[str, np.ndarray] = {}
        self._sample = self._sample_key = self._anchored_sample = None
        self._min_delay = None
        self.stream_age, self.stream_horizon = np.nan, 0.0
        self.truth = np.full(24, np.nan)
        self.command_filter = CommandFilter(self.robot, q0, self.config.safety, self.dt)
        self._held = {k: (pin.SE3(v), np.zeros(6), np.zeros(6)) for k, v in self.reference_poses.items()}
        self._last_valid: dict | None = None
        self._last_valid_row: int | None = None
        self._filtered: dict[str, pin.SE3] = {}
        self._valid_prev = None
        self._loss_start = None
        self._wall0 = None
        self.record_t: list[float] = []
        self.record_valid: list[bool] = []
        self._pose_log: list = []  # per tick: the poses (3, 12), or the common tick's row (`record_pose`)
        self.clamped_ticks = {k: 0 for k in DEFAULT_TARGETS}
        self.loss_events = 0
        self.loss_durations: list[float] = []
        if self.link is not None:  # the common tick's rows: only for a recording replayed directly
            self._rows = None
        elif self._rows is not None:
            self._engaged_rows()
            self.command_filter.bind_rows(DEFAULT_TARGETS)
            index = {e: i for i, e in enumerate(DEFAULT_TARGETS)}
            self._row_tasks = tuple((index[e], tuple(tasks)) for e, tasks in self.task_names.items())

    def _fixed_feet(self, recording: MocapRecording):
        """The recording with the operator's walk and turns taken out (`locomotion`, human/locomotion.py)."""
        from ..io.skeleton_map import map_segments

        names = self.config.segment_map
        if names is None:
            try:
                names = map_segments(recording.segments, recording.parents, recording.source).names
            except ConfigError:
                return recording, None  # the retargeting says what is missing
        up = (recording.conventions or {}).get("up") or f"+{recording.up_axis}"
        self.walk_source = (recording, names, up)  # what `locomotion: stepping` reads the operator's steps from
        return fix_feet(recording, names, up, self.config.locomotion)

    #: None, or (t, targets) -> targets: the effector targets moved with the robot's own walk (`carry`)
    carrier = None

    def carry(self, carrier) -> None:
        """Move every tick's effector targets (pose, velocity, acceleration, after the engagement blend and before
        the command filter) with `carrier(t, targets)`: the robot's walking frame under `locomotion: stepping`.
        The common tick's stacked rows are not used then."""
        self.carrier = carrier
        self._rows = None

    def skeleton_summary(self) -> dict:
        """How the source's skeleton was read: the length unit, the up axis and the segment mapping."""
        m = self.retargeter.segment_mapping
        method = "file" if self.config.segment_map is not None else (m.method if m is not None else "names")
        names = self.config.segment_map if self.config.segment_map is not None else (m.names if m else None)
        return {"length_unit": getattr(self.source, "length_unit_note", "") or None,
                "up_axis": getattr(self.source, "up_axis", None), "mapping": method, "segments": names,
                "conventions": dict(getattr(self.source, "conventions", None) or {}) or None,
                "operator_motion": self.operator_motion.as_dict() if self.operator_motion is not None else None}

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
        dt = self.dt
        duration = self.duration
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
        # one array per quantity, effectors stacked (the common tick reads rows of them); the dicts are views
        valid = inside & frame_valid[k]
        stacked = {}
        for key in ("position", "rotation", "velocity", "acceleration"):
            stacked[key] = np.ascontiguousarray(np.stack([out[key][e] for e in DEFAULT_TARGETS], axis=1),
                                                dtype=np.float64)
            out[key] = {e: stacked[key][:, i] for i, e in enumerate(DEFAULT_TARGETS)}
        clamped = np.stack([out["clamped"][e] for e in DEFAULT_TARGETS], axis=1)
        self._rows = _Rows(stacked["position"], stacked["rotation"], stacked["velocity"], stacked["acceleration"],
                           valid.tolist(), clamped, clamped.any(axis=1).tolist())
        return _Trajectory(**out, valid=valid)

    def _recorded_targets(self, t: float) -> tuple[dict, bool, dict]:
        tr = self.trajectory
        k = min(int(round(t / self.dt)), tr.n - 1)
        return self._trajectory_row(k), bool(tr.valid[k]), {e: bool(tr.clamped[e][k]) for e in DEFAULT_TARGETS}

    def _trajectory_row(self, k: int) -> dict:
        tr = self.trajectory
        return {e: (pin.SE3(tr.rotation[e][k], tr.position[e][k]), tr.velocity[e][k].copy(),
                    tr.acceleration[e][k].copy()) for e in DEFAULT_TARGETS}

    def _engaged_rows(self) -> None:
        """The engagement blend of the valid rows of ticks k with k dt < engage_time, at t = k dt (`_Rows`)."""
        rows = self._rows
        n = 0
        while n < rows.P.shape[0] and n * self.dt < self.engage_time:
            n += 1
        P, R = np.empty((n, 3, 3)), np.empty((n, 3, 3, 3))
        V, A = np.empty((n, 3, 6)), np.empty((n, 3, 6))
        ok = rows.valid[:n]
        for k in (k for k in range(n) if ok[k]):
            blended = self._engage(k * self.dt, self._trajectory_row(k))
            for i, e in enumerate(DEFAULT_TARGETS):
                M, vel, acc = blended[e]
                P[k, i], R[k, i], V[k, i], A[k, i] = M.translation, M.rotation, vel, acc
        rows.engaged, rows.engaged_ok = (P, R, V, A), ok

    def _row_targets(self, t: float) -> dict | None:
        """The common tick of a recording, from the stacked rows: a valid row (blended from the precomputed
        engagement rows while t < engage_time) that the command filter lets through untouched; the same
        bookkeeping and references as `targets` without building a pose object. None where it is not that tick
        (invalid, an engagement time off the tick grid, a filter intervention): `targets` does it."""
        rows = self._rows
        k_tick = int(round(t / self.dt))
        k = min(k_tick, len(rows.valid) - 1)
        if not rows.valid[k]:
            return None
        if t < self.engage_time:
            ok = rows.engaged_ok
            if not (k_tick < len(ok) and ok[k_tick] and t == k_tick * self.dt):
                return None
            P, R, V, A = rows.engaged
            j = k_tick
        else:
            P, R, V, A, j = rows.P, rows.R, rows.V, rows.A, k
        if not self.command_filter.pass_rows(t, j, P, R, V, A):
            return None
        # what `targets` does on a valid tick
        self._end_loss(t)
        self._last_valid, self._last_valid_row = None, k
        self._hold_from = None
        self._valid_prev = True
        if rows.any_clamped[k]:
            for i, e in enumerate(DEFAULT_TARGETS):
                self.clamped_ticks[e] += int(rows.clamped[k, i])
        self.record_t.append(t)
        self.record_valid.append(True)
        self._pose_log.append(j if P is rows.P else -1 - j)  # the row, read when `record_pose` is
        named = {}
        unchecked = PoseReference.unchecked
        for i, tasks in self._row_tasks:
            ref = unchecked(P[j, i], R[j, i], V[j, i], A[j, i])
            for task in tasks:
                named[task] = ref
        return named

    def _end_loss(self, t: float) -> None:
        """A valid tick after lost ones: the loss's duration counted."""
        if self._valid_prev is False and self._loss_start is not None:
            self.loss_durations.append(t - self._loss_start)
            self._loss_start = None

    @property
    def record_pose(self) -> dict[str, np.ndarray]:
        """Per effector, the references handed to the controller each tick (position, rotation row-major; NaN
        where the effector had none), (ticks, 12)."""
        out = np.full((len(self._pose_log), len(DEFAULT_TARGETS), 12), np.nan)
        rows = self._rows
        for c, entry in enumerate(self._pose_log):
            if isinstance(entry, np.ndarray):
                out[c] = entry
            else:  # a row of the common tick: of the trajectory (j >= 0) or of the engagement blend (-1 - j)
                P, R = (rows.P, rows.R) if entry >= 0 else rows.engaged[:2]
                j = entry if entry >= 0 else -1 - entry
                out[c, :, :3] = P[j]
                out[c, :, 3:] = R[j].reshape(-1, 9)
        return {e: out[:, i] for i, e in enumerate(DEFAULT_TARGETS)}

    def _last_valid_targets(self) -> dict | None:
        """The last valid tick's targets before the engagement blend (kept as a row index by the common tick)."""
        if self._last_valid is None and self._last_valid_row is not None:
            return self._trajectory_row(self._last_valid_row)
        return self._last_valid

    def _live_targets(self, t: float) -> tuple[dict, bool, dict]:
        if self.realtime:
            if self._wall0 is None:
                self._wall0 = time.monotonic() - t
            ahead = t - (time.monotonic() - self._wall0)
            if ahead > 0:
                time.sleep(ahead)
        sample = self.retargeter.sample(t)
        latest = self.source.latest
        age = np.nan
        if latest is not None:
            # no shared clock: the age past the fastest delivery seen, plus the latency the receiver cannot see
            delay = latest.arrival - latest.timestamp
            self._min_delay = delay if self._min_delay is None else min(self._min_delay, delay)
            age = self.source.now() - latest.timestamp - self._min_delay + self.config.predict_latency
        return self._stream_targets(t, sample, None if latest is None else latest.timestamp, age)

    def _link_targets(self, t: float) -> tuple[dict, bool, dict]:
        """A recording through the simulated impaired link: what a live receiver holds at t (shared clock)."""
        frame = self.link.frame_at(t)
        key = None if frame is None else (frame.time, frame.valid)
        if key != self._sample_key or self._sample is None:  # retarget a frame once
            self._sample, self._sample_key = self.retargeter.sample_frame(frame, t), key
        sample = self._sample
        age = np.nan if frame is None else self.link.sender_time(t) - frame.time
        return self._stream_targets(t, sample, None if frame is None else frame.time, age)

    def _stream_targets(self, t: float, sample, frame_time: float | None, age: float) -> tuple[dict, bool, dict]:
        """A stream's newest frame (retargeted `sample`, sender time stamp `frame_time`, `age` [s] at t) ->
        targets: the anchor, the prediction over the frame's age, the first-order filter."""
        if self.anchor != "absolute" and sample.valid and not self.calibration_positions:
            self._set_anchor(sample.references)
        if sample is not self._anchored_sample:  # anchor a sample once
            anchored = {k: self._anchored(k, M.translation) for k, M in sample.references.items()}
            self._anchored_refs = ({k: pin.SE3(M.rotation, anchored[k][0][0]) for k, M in sample.references.items()},
                                   {k: bool(c or anchored[k][1][0]) for k, c in sample.clamped.items()})
            self._anchored_sample = sample
        refs, clamped = dict(self._anchored_refs[0]), self._anchored_refs[1]
        horizon, rates = 0.0, {}
        if sample.valid:
            if frame_time is not None and frame_time != self.predictor.newest_time:
                self.predictor.push(frame_time, refs)
            # the horizon covers the frame's age and the filter's own lag (a first-order filter trails a ramp by
            # its time constant)
            predicted, rates, horizon = self.predictor.predict(age + self.smoothing)
            refs.update(predicted)
        self.stream_age, self.stream_horizon = float(age), horizon
        alpha = 1.0 if self.smoothing <= 0 else 1.0 - np.exp(-self.dt / self.smoothing)
        ff = self.speed if self.feedforward else 0.0
        out = {}
        for e, M in refs.items():
            prev = self._filtered.get(e)
            v = ff * rates.get(e, np.zeros(6))
            if prev is None or not sample.valid:
                F = pin.SE3(M)
            else:
                F = pin.SE3(prev.rotation @ pin.exp3(alpha * pin.log3(prev.rotation.T @ M.rotation)),
                            prev.translation + alpha * (M.translation - prev.translation))
                v = self._filtered_rate[e] + alpha * (v - self._filtered_rate[e])
            if sample.valid:
                self._filtered[e], self._filtered_rate[e] = F, v
            out[e] = (F, v if sample.valid else np.zeros(6), np.zeros(6))
        return out, bool(sample.valid), clamped

    @property
    def watchdog(self) -> dict | None:
        """The skeleton watchdog's trip (time, frame time, reason) once it has held the robot, else None."""
        return self.retargeter.watchdog

    def follow(self, t: float, q: np.ndarray) -> None:
        """The robot's measured configuration q at t (base estimate and encoders): the command filter's body
        spheres follow it."""
        self.command_filter.follow(t, q)

    def targets(self, t: float) -> dict:
        """The named frame-task references at time t [s] (effector targets through the anchor, spline or filter,
        signal-loss policy and engagement blend), with the health bookkeeping."""
        if self._rows is not None:
            named = self._row_targets(t)
            if named is not None:
                return named
        if self.link is not None:
            targets, valid, clamped = self._link_targets(t)
        else:
            targets, valid, clamped = (self._live_targets(t) if self.live else self._recorded_targets(t))
        if valid:
            self._end_loss(t)
            self._last_valid, self._last_valid_row = targets, None  # held (at rest) if the stream is lost
            self._hold_from = None
        else:
            if self._valid_prev is not False:
                # a loss starts (before any valid frame this is the start of the run)
                if self._valid_prev is True:
                    self.loss_events += 1
                self._loss_start = t
                last_valid = self._last_valid_targets()
                if last_valid is not None:
                    self._held = {k: (pin.SE3(v[0]), np.zeros(6), np.zeros(6)) for k, v in last_valid.items()}
                    self._last_valid, self._last_valid_row = None, None
                self._hold_from = {k: pin.SE3(v[0]) for k, v in self._held.items()}
            targets = self._safe_targets(t)
        self._valid_prev = valid
        if t < self.engage_time:
            targets = self._engage(t, targets)
        if self.carrier is not None:  # the robot walks (`locomotion: stepping`): the targets go with it
            targets = self.carrier(t, targets)
        targets = self.command_filter(t, targets)  # last: nothing unfiltered reaches the controller
        if self.link is not None:
            # the undelayed reference: what the robot would be asked without the link (the recording's spline)
            truth = self._recorded_targets(t)[0]
            if t < self.engage_time:
                truth = self._engage(t, truth)
            self.truth = np.concatenate([np.concatenate([truth[h][0].translation, truth[h][0].rotation.reshape(-1)])
                                         for h in HANDS])
        for k, c in clamped.items():
            self.clamped_ticks[k] += int(c)
        self.record_t.append(t)
        self.record_valid.append(valid)
        poses = np.full((len(DEFAULT_TARGETS), 12), np.nan)
        for i, k in enumerate(DEFAULT_TARGETS):
            if k in targets:
                M = targets[k][0]
                poses[i, :3] = M.translation
                poses[i, 3:] = M.rotation.reshape(-1)
        self._pose_log.append(poses)
        named = {}
        for effector, tasks in self.task_names.items():
            if effector not in targets:  # garbage before any valid reference: the task keeps its own
                continue
            M, vel, acc = targets[effector]
            ref = PoseReference(M.translation, M.rotation, vel, acc)
            for task in tasks:
                named[task] = ref
        return named

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

