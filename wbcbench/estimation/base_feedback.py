"""Base feedback for controllers that integrate their own model (IK, TSID position): keeps the walk on its plan
in the world although the integrated model drifts from the real robot.

A position-controlled robot rocks on its soft soles and its joints lag their references, so the real robot's feet
land a little off where the integrated model put them, and the model never hears of it: over a walk the real
robot ends up turned and shifted with respect to the model (IK on the platforms: 5 deg of yaw, 10 cm sideways).

The drift is the planar rigid transform D (yaw, x, y) that takes the real robot to the model. It is estimated from
the feet in double support, as the balance estimator anchors its CoM (estimation/balance.py): for each foot in contact,
D_foot = P(T_model_foot) P(T_measured_foot)^-1 with P the planar pose of a sole (x, y, heading of its x axis),
T_model_foot from the integrated configuration and T_measured_foot from the Measurement (base pose from the
robot's base estimator, joints from the encoders); the feet's D are averaged and low-pass filtered (time constant
`time_constant`). The estimate is held in single support, where the robot rocks on its stance sole.

The correction moves the plan into the model's world: the CoM and swing-foot references and the trunk orientation
target are mapped through D, so the model walks the plan shifted by the drift and the real robot walks the plan.
(Moving the integrated configuration to the real robot instead would be undone at once by the contact tasks,
which hold the model's feet where they touched down.) The ZMP reference stays in the world: the stabilizer
compares it with the ZMP measured there.

A foot lands under the estimate of its touch-down and the contact task holds the model's foot there; the next
double support updates D, so at lift-off the mapped plan no longer starts where the model's foot stands. The
swing reference therefore starts at the model's foot and passes to the mapped plan with a quintic blend over
`liftoff_blend` seconds (the offset's velocity and acceleration added to the reference's). Without it the swing
task pulled the model's foot by the change of D in one tick and the ZMP peaked at each lift-off (IK on the
platforms: 0.42 m against 0.21 m without base feedback).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..robots import Robot
from ..jit import c_view, njit
from ..side import Side
from ..tasks.placements import ForwardKinematics, frame_placements
from ..types import Measurement, PointReference, PoseReference, References
from ._memo import joints_placing, memo_arrays, memo_joint_placements, placement_memo

__all__ = ["BaseFeedbackConfig", "BaseFeedback"]


@dataclass(frozen=True)
class BaseFeedbackConfig:
    """Attributes:
        time_constant: first-order filter on the drift estimate [s] (> 0).
        liftoff_blend: duration [s] over which a lifted foot's reference passes from where the model's foot
            stood to the plan mapped by the current drift (module docstring); 0 (default): at once.
    """

    time_constant: float = 1.0
    liftoff_blend: float = 0.0

    def __post_init__(self) -> None:
        if not np.isfinite(self.time_constant) or self.time_constant <= 0.0:
            raise ValueError(f"BaseFeedbackConfig.time_constant must be > 0 s, got {self.time_constant!r}")
        if not np.isfinite(self.liftoff_blend) or self.liftoff_blend < 0.0:
            raise ValueError(f"BaseFeedbackConfig.liftoff_blend must be >= 0 s, got {self.liftoff_blend!r}")


@njit
def _drift_step(q_model, q_meas, memo_ints, memo_floats, frame_parents, R_frames, t_frames, R, t, drift, alpha):
    """The drift step with both feet in contact (of `_double_support_step`, i.e. of `BaseFeedback.update` and
    `correct`): the soles' placements for the model's and the measured configuration (`placements.joint_placements`
    through the model's memo (`_memo.memo_joint_placements`), `frame_placements`; rows model left, right, measured
    left, right into ``R`` (4, 3, 3), ``t`` (4, 3); of the joints up to the soles' only), then `_drift_from_soles`.
    The memo and the model's constants come as its two buffers (`PlacementMemo.ints`, `floats`)."""
    kinds, parents, idx_q, R0, t0, memo_q, memo_R, memo_t, memo_state, memo_work = memo_arrays(memo_ints, memo_floats)
    upto = joints_placing(frame_parents)  # the legs: the soles' joints and those before them
    j = memo_joint_placements(q_model, kinds, parents, idx_q, R0, t0, memo_q, memo_R, memo_t, memo_state,
                              memo_work, upto)
    frame_placements(memo_R[j], memo_t[j], frame_parents, R_frames, t_frames, R[:2], t[:2])
    j = memo_joint_placements(q_meas, kinds, parents, idx_q, R0, t0, memo_q, memo_R, memo_t, memo_state,
                              memo_work, upto)
    frame_placements(memo_R[j], memo_t[j], frame_parents, R_frames, t_frames, R[2:], t[2:])
    _drift_from_soles(R, t, drift, alpha)


@njit(exact=True, inline=True)
def _drift_step_transform(q_model, q_meas, memo_ints, memo_floats, frame_parents, R_frames, t_frames, R, t, drift,
                          alpha, R_drift, p_drift):
    """`_drift_step`, then D = (``R_drift`` (3, 3), ``p_drift`` (3,)) of the new drift (`BaseFeedback._transform`'s
    numbers: the same cosine and sine). Inlined: its compiled callers are all `exact`, as it is."""
    _drift_step(q_model, q_meas, memo_ints, memo_floats, frame_parents, R_frames, t_frames, R, t, drift, alpha)
    _transform_of(drift, R_drift, p_drift)


@njit(exact=True)
def _double_support_step(q_model, q_meas, memo_ints, memo_floats, frame_parents, floats, drift_prev, com_position,
                         com_velocity, com_acceleration, out):
    """A double-support tick of `BaseFeedback.correct` up to the feet's references, in one call: the drift
    ``drift_prev`` updated (`_drift_step_transform`) and the CoM reference mapped through the new D (`_map_point`;
    skipped for an empty ``com_position``). ``out`` (24,): the new drift (3) | R_drift (9, row-major) | p_drift (3)
    | the mapped CoM (9); ``floats``: the base feedback's buffer (`_feedback_arrays`)."""
    alpha, R_frames, t_frames, R, t = _feedback_arrays(frame_parents.shape[0], floats)
    drift = out[0:3]
    for a in range(3):
        drift[a] = drift_prev[a]
    R_drift, p_drift = c_view(out[3:12], (3, 3)), out[12:15]
    _drift_step_transform(q_model, q_meas, memo_ints, memo_floats, frame_parents, R_frames, t_frames, R, t, drift,
                          alpha, R_drift, p_drift)
    if com_position.shape[0] == 3:
        _map_point(R_drift, p_drift, com_position, com_velocity, com_acceleration, out[15:24])


@njit(inline=True)
def _feedback_arrays(k, floats):
    """The arrays of `BaseFeedback`'s buffer (``k`` sole frames; as `BaseFeedback` lays it out): ``(alpha,
    R_frames (k, 3, 3), t_frames (k, 3), R (2k, 3, 3), t (2k, 3))``, the filter's gain, the soles' placements in
    their joints and the scratch rows of the soles' placements, views."""
    o = 1 + 9 * k
    return (floats[0], c_view(floats[1:o], (k, 3, 3)), c_view(floats[o:o + 3 * k], (k, 3)),
            c_view(floats[o + 3 * k:o + 21 * k], (2 * k, 3, 3)), c_view(floats[o + 21 * k:o + 27 * k], (2 * k, 3)))


@njit(exact=True, inline=True)
def _transform_of(drift, R, p):
    """D = (R (3, 3), p (3,)) of the drift (x, y, yaw): a rotation about z by yaw and the translation (x, y, 0).
    Inlined: its compiled callers are all `exact`, as it is."""
    c, s = np.cos(drift[2]), np.sin(drift[2])
    R[0, 0], R[0, 1], R[0, 2] = c, -s, 0.0
    R[1, 0], R[1, 1], R[1, 2] = s, c, 0.0
    R[2, 0], R[2, 1], R[2, 2] = 0.0, 0.0, 1.0
    p[0], p[1], p[2] = drift[0], drift[1], 0.0


@njit(inline=True)
def _drift_from_soles(R, t, drift, alpha):
    """From the soles' placements ``R`` (4, 3, 3), ``t`` (4, 3) (rows model left, right, measured left, right):
    the planar drift of each sole, their mean, and the filter (gain ``alpha``) on ``drift`` (3,: x, y, yaw), in
    place. Planar poses first (x, y, heading of each sole): a tilted sole (slopes, rocking) must not turn its
    roll/pitch difference into a translation of D. Inlined: its compiled callers are all reassociating (not
    `exact`), as it is."""
    raw0 = raw1 = raw2 = 0.0
    for i in range(2):
        a2 = np.arctan2(R[i, 1, 0], R[i, 0, 0])
        b0, b1, b2 = t[2 + i, 0], t[2 + i, 1], np.arctan2(R[2 + i, 1, 0], R[2 + i, 0, 0])
        d = a2 - b2 - drift[2]
        dyaw = drift[2] + np.arctan2(np.sin(d), np.cos(d))
        c, si = np.cos(dyaw), np.sin(dyaw)
        raw0 += (t[i, 0] - (c * b0 - si * b1)) / 2.0
        raw1 += (t[i, 1] - (si * b0 + c * b1)) / 2.0
        raw2 += dyaw / 2.0
    drift[0] = drift[0] + alpha * (raw0 - drift[0])
    drift[1] = drift[1] + alpha * (raw1 - drift[1])
    drift[2] = drift[2] + alpha * (raw2 - drift[2])


@njit(inline=True)
def _rotate(R, x, out, k):
    """``out[k:k+3] = R x`` (x (3,)). Inlined: its compiled callers are all reassociating (not `exact`), as it
    is."""
    for a in range(3):
        out[k + a] = R[a, 0] * x[0] + R[a, 1] * x[1] + R[a, 2] * x[2]


@njit
def _map_point(R, p, position, velocity, acceleration, out):
    """A point's reference through D = (R, p): ``out`` (9,) = R position + p, R velocity, R acceleration."""
    _rotate(R, position, out, 0)
    for a in range(3):
        out[a] += p[a]
    _rotate(R, velocity, out, 3)
    _rotate(R, acceleration, out, 6)


@njit
def _map_pose(R, p, position, rotation, velocity, acceleration, out):
    """A frame's reference through D = (R, p): ``out`` (24,) = R position + p, R rotation (row-major; skipped for
    an empty ``rotation``), then both twists with each of their linear and angular parts rotated."""
    _rotate(R, position, out, 0)
    for a in range(3):
        out[a] += p[a]
    if rotation.shape[0] == 3:
        for a in range(3):
            for b in range(3):
                out[3 + 3 * a + b] = R[a, 0] * rotation[0, b] + R[a, 1] * rotation[1, b] + R[a, 2] * rotation[2, b]
    _rotate(R, velocity[:3], out, 12)
    _rotate(R, velocity[3:], out, 15)
    _rotate(R, acceleration[:3], out, 18)
    _rotate(R, acceleration[3:], out, 21)


@njit(exact=True)
def _liftoff_offset(position, velocity, acceleration, dp, dphi, b, db, ddb, out):
    """`BaseFeedback._from_liftoff`'s offset of a swing foot's reference, element by element as numpy did it:
    ``out`` (15,) = position + (1 - b) dp, velocity and acceleration with db dp, ddb dp taken from their linear
    parts and db dphi, ddb dphi from their angular parts (unchanged for an empty ``dphi``)."""
    c = 1.0 - b
    for a in range(3):
        out[a] = position[a] + c * dp[a]
    for a in range(6):
        out[3 + a] = velocity[a]
        out[9 + a] = acceleration[a]
    for a in range(3):
        out[3 + a] -= db * dp[a]
        out[9 + a] -= ddb * dp[a]
    if dphi.shape[0] == 3:
        for a in range(3):
            out[6 + a] -= db * dphi[a]
            out[12 + a] -= ddb * dphi[a]


_NO_ROTATION = np.zeros((0, 3))
_NO_POINT = np.zeros(0)
_LEFT, _RIGHT = Side.LEFT, Side.RIGHT


def _mapped_pose(R: np.ndarray, p: np.ndarray, ref: PoseReference) -> PoseReference:
    """A frame's reference through D = (R, p), in one compiled call (`_map_pose`): views of one new array."""
    out = np.empty(24)
    rot = ref.rotation
    if rot is None:
        _map_pose(R, p, ref.position, _NO_ROTATION, ref.velocity, ref.acceleration, out)
        return PoseReference.unchecked(out[:3], None, out[12:18], out[18:24])
    _map_pose(R, p, ref.position, rot, ref.velocity, ref.acceleration, out)
    return PoseReference.unchecked(out[:3], out[3:12].reshape(3, 3), out[12:18], out[18:24])


class BaseFeedback:
    """Drift of the integrated model from the real robot, and the references mapped into the model's world.

    Args:
        robot: the robot (sole frames from its profile).
        dt: control period [s].
        config: filter settings.
    """

    def __init__(self, robot: Robot, dt: float, config: BaseFeedbackConfig = BaseFeedbackConfig()):
        self.model = robot.model
        self.data_meas = robot.model.createData()
        self.data_model = robot.model.createData()
        self.sole_ids = {s: robot.sole_frame_id(s) for s in Side}
        # the drift step in one compiled call (`_double_support_step`) where the compiled forward kinematics applies
        # (its placements are pinocchio's to rounding): pinocchio's two passes and four frame updates and the numpy
        # around them took 45 us of a 480 us IK step
        self._fk = fk = ForwardKinematics(robot.model)
        self.alpha = alpha = 1.0 - np.exp(-dt / config.time_constant)
        frame_parents, R_frames, t_frames = fk.frame_arrays([self.sole_ids[s] for s in Side])
        # the double-support kernel's floats in one buffer (`_feedback_arrays`): the gain, the soles' placements in
        # their joints, the soles' placements (rows model left, right, measured left, right; `_soles` views them,
        # for pinocchio's placements where the compiled ones do not apply)
        self._floats = floats = np.concatenate([[alpha], R_frames.ravel(), t_frames.ravel(), np.zeros(4 * 12)])
        o = 1 + 12 * 2
        self._soles = (floats[o:o + 36].reshape(4, 3, 3), floats[o + 36:].reshape(4, 3))
        if fk.supported:
            memo = placement_memo(robot.model, fk)
            self._double_support_args = (memo.ints, memo.floats, frame_parents, floats)
        self.blend = config.liftoff_blend
        self.drift = np.zeros(3)   # (x [m], y [m], yaw [rad]) of D
        self._liftoff: dict[Side, tuple[float, np.ndarray, np.ndarray | None]] = {}

    def reset(self) -> None:
        self.drift = np.zeros(3)
        self._liftoff = {}

    def update(self, meas: Measurement, q_model: np.ndarray, contacts) -> np.ndarray:
        """Update and return the drift estimate (x, y, yaw) from the feet in `contacts`; unchanged unless both
        feet are in contact (in single support the robot rocks on its stance sole, and updating there made TSID
        position fall on the platforms)."""
        if _LEFT not in contacts or _RIGHT not in contacts:
            return self.drift
        if self._fk.supported:
            self._double_support(q_model, meas.q, None)
            return self.drift
        # other joint types: pinocchio's placements
        drift = self.drift.copy()  # a new array each update (callers may keep the last one)
        m = self.model
        R, t = self._soles
        for k, (d, q) in enumerate(((self.data_model, q_model), (self.data_meas, meas.q))):
            pin.forwardKinematics(m, d, q)
            for i, s in enumerate(Side):
                M = pin.updateFramePlacement(m, d, self.sole_ids[s])
                R[2 * k + i], t[2 * k + i] = M.rotation, M.translation
        _drift_from_soles(R, t, drift, self.alpha)
        self.drift = drift
        return drift

    def _double_support(self, q_model: np.ndarray, q_meas: np.ndarray, com: PointReference | None) -> np.ndarray:
        """The compiled double-support tick (`_double_support_step`): the drift updated from both soles, D and,
        given a CoM reference, its mapping, in one new array (24,); the drift becomes a view of it (a new array
        each update: callers may keep the last one)."""
        out = np.empty(24)
        m_ints, m_floats, parents, floats = self._double_support_args  # a call without *: no tuple built
        if com is None:
            _double_support_step(q_model, q_meas, m_ints, m_floats, parents, floats, self.drift, _NO_POINT,
                                 _NO_POINT, _NO_POINT, out)
        else:
            _double_support_step(q_model, q_meas, m_ints, m_floats, parents, floats, self.drift, com.position,
                                 com.velocity, com.acceleration, out)
        self.drift = out[:3]
        return out

    def transform(self) -> tuple[np.ndarray, np.ndarray]:
        """D as (R (3, 3), p (3,)): a world point x maps to R x + p in the model's world."""
        R, p = self._transform()
        return R.copy(), p.copy()

    _cached = (None, None, None, None)

    def _transform(self) -> tuple[np.ndarray, np.ndarray]:
        """`transform`'s arrays, made again only when the drift estimate changed (not to be modified): views of
        the array of the double-support tick that computed them (`correct`), or computed here."""
        drift, R, p, out = self._cached
        if drift is not self.drift:
            x, y, yaw = self.drift
            c, s = np.cos(yaw), np.sin(yaw)
            R, p = np.array((c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)).reshape(3, 3), np.array((x, y, 0.0))
            self._cached = (self.drift, R, p, None)
        elif R is None:
            R, p = out[3:12].reshape(3, 3), out[12:15]
            self._cached = (drift, R, p, out)
        return R, p

    def correct(self, meas: Measurement, refs: References, q_model: np.ndarray) -> References:
        """`refs` mapped into the integrated model's world (module docstring), after one `update` with the feet
        the references put in contact."""
        contacts = refs.contacts
        com = refs.com
        # the mapped arrays are views of new float64 arrays, of the checked references' shapes: the fast
        # constructors; each reference mapped in one compiled call
        if _LEFT in contacts and _RIGHT in contacts and self._fk.supported:
            # `update`, D and the CoM's mapping in one compiled call, into one new array: D's views made when asked
            # for (`_transform`: standing, nothing else is mapped)
            out = self._double_support(q_model, meas.q, com)
            if com is not None:
                com = PointReference.unchecked(out[15:18], out[18:21], out[21:24])
            self._cached = (self.drift, None, None, out)
        else:
            self.update(meas, q_model, contacts)
            if com is not None:
                R, p = self._transform()
                out = np.empty(9)
                _map_point(R, p, com.position, com.velocity, com.acceleration, out)
                com = PointReference.unchecked(out[:3], out[3:6], out[6:9])
        targets = refs.targets
        feet = refs.feet  # none: the plan's (empty) dict
        if feet or "waist" in targets:
            targets, feet = self._mapped_frames(refs, q_model)
        liftoff = self._liftoff
        if liftoff:
            for s in list(liftoff):
                if s in contacts or s not in refs.feet:
                    del liftoff[s]
        return refs.corrected(com, targets, refs.wrench_targets, refs.contact_poses, feet=feet)

    def _mapped_frames(self, refs: References, q_model: np.ndarray) -> tuple[dict, dict]:
        """The targets (the waist's mapped) and the feet's references (each mapped, a swing foot's from its
        lift-off: `_from_liftoff`) of `correct`."""
        R, p = self._transform()
        targets = refs.targets
        if "waist" in targets:
            targets = {**targets, "waist": _mapped_pose(R, p, targets["waist"])}
        contacts = refs.contacts
        feet = {}
        for s, f in refs.feet.items():
            mapped = _mapped_pose(R, p, f)
            feet[s] = mapped if s in contacts else self._from_liftoff(s, mapped, refs.t, q_model)
        return targets, feet

    def _from_liftoff(self, side: Side, ref: PoseReference, t: float, q_model: np.ndarray) -> PoseReference:
        """A swing foot's mapped reference `ref`, offset so that it starts where the model's foot stood at lift-off
        (the foot touched down under the drift estimate of its landing, which double support has updated since:
        without this the swing task would pull the model's foot by that difference in one tick), the offset
        fading out with a quintic blend over `liftoff_blend` seconds."""
        if side not in self._liftoff:
            pin.forwardKinematics(self.model, self.data_model, q_model)
            T = pin.updateFramePlacement(self.model, self.data_model, self.sole_ids[side])
            dphi = None if ref.rotation is None else pin.log3(T.rotation @ ref.rotation.T)
            self._liftoff[side] = (t, T.translation - ref.position, dphi)
        t0, dp, dphi = self._liftoff[side]
        if self.blend <= 0.0:
            return ref
        u = (t - t0) / self.blend
        if u >= 1.0:
            return ref
        u = max(u, 0.0)
        b = u ** 3 * (10.0 - 15.0 * u + 6.0 * u * u)
        db = 30.0 * u * u * (1.0 - u) ** 2 / self.blend
        ddb = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / self.blend ** 2
        out = np.empty(15)  # position, velocity, acceleration offset in one compiled call
        _liftoff_offset(ref.position, ref.velocity, ref.acceleration, dp, _NO_POINT if dphi is None else dphi, b, db,
                        ddb, out)
        rot = ref.rotation
        if dphi is not None:
            rot = pin.exp3((1.0 - b) * dphi) @ rot
        return PoseReference.unchecked(out[:3], rot, out[3:9], out[9:15])
