"""The force-based stabilizer of whole-body teleoperation, paper 004 (Dalin et al. 2021) Section III, Eq. 2-7.

Four strategies, each switchable with its gains in the task set's `stabilizer:` section (`type: force`), all driven by
the ankle force/torque sensors (contact wrenches by `measured_wrench`, the per-tick twin of
`estimation.contact_wrench_from_ft`: the foot below the sensor removed) and by the controller's model (the QP's
contact wrenches of the previous tick):

* `com_admittance` (Eq. 2, after Caron et al. 2019): the CoM reference (x, y) moves by the difference between
  the model's CoP (ZMP of the QP wrenches) and the measured one:
      c* = c - kd (p_model - p_meas),  c_dot* = c_dot - kv (p_model - p_meas) / dt,
      c_ddot* = c_ddot - ka (p_model - p_meas) / dt^2
* `ankle_admittance` (Eq. 3): each loaded foot's contact reference is tilted so that its measured CoP goes to
  the middle of the sole: pitch about the sole's y axis -kd_pitch * c_x, roll about its x axis +kd_roll * c_y
  (c the measured CoP in the sole frame, relative to the sole centre; the signs lift the loaded edge, as in the
  authors' inria_wbc). Only the position gain: the contact task of the QP takes a pose reference only.
* `foot_force_difference` (Eq. 4-5, after Kajita et al. 2010): the torso roll reference moves by
      D = (f_Lz - f_Rz) - (f_Lz^m - f_Rz^m)       (model minus measured left-right normal-force difference)
      roll* = roll - kd D,  omega_x* = -kv D / dt,  omega_dot_x* = -ka D / dt^2
  Eq. 4 as printed takes absolute values, |f_Lz - f_Rz| - |f_Lz^m - f_Rz^m|, which makes the correction blind
  to which foot is overloaded; the signed difference is Kajita's (and inria_wbc's). Positive roll (about world
  x) moves the upper body to the right, unloading the left foot.
* `zmp_distributor` (Eq. 6-7, after Kajita et al. 2010): a ZMP p is split between the feet, alpha the
  position of p projected on the segment from the left to the right sole centre (0 at the left foot):
      f_R = alpha M g,  f_L = (1 - alpha) M g   (normal forces, ground on robot, so positive here),
      tau_0 = sum_i (p - p_i) x f_i  (the ankle moment making the feet's ZMP p), its pitch (y) part split as the
      normal forces, its roll (x) part given to the foot on the side it loads;
  F = split of the reference ZMP (the CoM reference's cart-table ZMP), F^d = split of the measured ZMP,
      F* = F - kp (F - F^d) - kd (F - F^d) / dt                                            (Eq. 7)
  F* are the targets of the contact-force regularisation, `weight ||w - F*||^2` in the QP (`References.wrench_targets`,
  weighted by the task set's `regularization.wrench_target`). In
  position and SPD modes only the total of the two wrenches reaches the motion (through the floating-base rows);
  the split matters in torque mode.

Units: SI; positions and CoPs in the world frame (x, y) unless stated; gains as in the paper (kd
dimensionless for Eq. 2, rad/m for Eq. 3, rad/N for Eq. 5; kv and ka the same units times one tick).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..config import Section
from ..estimation import FootMass, cross
from ..side import Side
from ..tasks.placements import ForwardKinematics
from ..types import GRAVITY, Measurement, ModelFeedback, PointReference, PoseReference, References
from . import _kernels as _k
from ._kernels import feet_measurement, filter_measurement, reference_split
from .base import Stabilizer

_SIDES = tuple(Side)  # iterating the enum itself costs a microsecond a loop
_LEFT, _RIGHT = Side.LEFT, Side.RIGHT

__all__ = [
    "reference_split",
    "AdmittanceGains",
    "ZmpDistributorGains",
    "TeleopStabilizerSpec",
    "parse_teleop_stabilizer",
    "com_admittance",
    "ankle_admittance",
    "foot_force_difference",
    "zmp_distributor",
    "wrench_admittance",
    "measured_wrench",
    "reference_wrench_targets",
    "split_to_local",
    "TeleopStabilizer",
]

_ZERO3 = np.zeros(3)
_ZERO6 = np.zeros(6)
_EYE3 = np.eye(3)
_NO_TORSO = (0.0, 0.0, 0.0, math.nan)   # `corrections`' torso gains when Eq. 4-5 is off
_NO_ANKLE = (0.0, 0.0, math.nan)        # and its ankle gains when Eq. 3 is off


# ---- specs ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class AdmittanceGains:
    """Gains of one admittance law of the paper (Eq. 2, 3, 5): position `kd`, velocity `kv`, acceleration `ka`
    (per axis where the law has several; x y for Eq. 2, pitch roll for Eq. 3, one for Eq. 5), and `limit`: the
    largest position correction (m or rad), None for none."""

    kd: tuple[float, ...]
    kv: tuple[float, ...]
    ka: tuple[float, ...]
    limit: float | None = None


@dataclass(frozen=True)
class ZmpDistributorGains:
    """Eq. 7 gains on the 6 wrench components (fx fy fz tx ty tz): `kp` (dimensionless) and `kd` (s)."""

    kp: tuple[float, ...]
    kd: tuple[float, ...]


@dataclass(frozen=True)
class TeleopStabilizerSpec:
    """Which strategies run (None: off) and the measurement filters: `cop_cutoff_hz` (first-order low-pass on
    the measured CoPs/ZMP and normal forces, None: unfiltered), `min_normal_force` [N] (a foot below it has no
    CoP)."""

    com_admittance: AdmittanceGains | None = None
    ankle_admittance: AdmittanceGains | None = None
    foot_force_difference: AdmittanceGains | None = None
    zmp_distributor: ZmpDistributorGains | None = None
    cop_cutoff_hz: float | None = None
    min_normal_force: float = 10.0
    torso_task: str = "torso"

    @property
    def enabled(self) -> bool:
        return any(x is not None for x in (self.com_admittance, self.ankle_admittance, self.foot_force_difference,
                                           self.zmp_distributor))


def _gains(sec: Section, n: int, names: str, *, kv_ka: bool = True) -> AdmittanceGains:
    def vec(key: str) -> tuple[float, ...]:
        return tuple(float(x) for x in _vector_or_scalar(sec, key, n, names))

    kd = vec("kd")
    kv = vec("kv") if kv_ka else (0.0,) * n
    ka = vec("ka") if kv_ka else (0.0,) * n
    limit = sec.float("limit", positive=True) if sec.has("limit") else None
    return AdmittanceGains(kd, kv, ka, limit)


def parse_teleop_stabilizer(s: Section) -> TeleopStabilizerSpec:
    """Parse a task set's `stabilizer:` section of `type: force` (errors name the file and key)."""
    parts = {}
    for key, n, names, kv_ka in (("com_admittance", 2, "x y", True), ("ankle_admittance", 2, "pitch roll", False),
                                 ("foot_force_difference", 1, "roll", True)):
        if s.has(key):
            g = s.section(key)
            if g.bool("enabled", True):
                parts[key] = _gains(g, n, names, kv_ka=kv_ka)
            else:
                for k in list(g.data):
                    g.raw(k)
            g.finish()
    if s.has("zmp_distributor"):
        z = s.section("zmp_distributor")
        if z.bool("enabled", True):
            parts["zmp_distributor"] = ZmpDistributorGains(
                kp=tuple(float(x) for x in _vector_or_scalar(z, "kp", 6)),
                kd=tuple(float(x) for x in _vector_or_scalar(z, "kd", 6)))
        else:
            for k in list(z.data):
                z.raw(k)
        z.finish()
    cutoff = s.raw("cop_cutoff_hz", None)
    spec = TeleopStabilizerSpec(**parts,
                                cop_cutoff_hz=None if cutoff is None else s.float("cop_cutoff_hz", positive=True),
                                min_normal_force=s.float("min_normal_force", 10.0, min=0.0),
                                torso_task=s.str("torso_task", "torso"))
    s.finish()
    return spec


def _vector_or_scalar(sec: Section, key: str, n: int, names: str | None = None) -> np.ndarray:
    """`key` as n non-negative gains: one number for all, or a list of n (`names` the axes, for the error)."""
    raw = sec.raw(key, 0.0)
    if isinstance(raw, (int, float)) and not isinstance(raw, bool):
        val = np.full(n, float(raw))
    else:
        val = sec.vector(key, length=n)
    if not np.all(np.isfinite(val)) or np.any(val < 0):
        axes = f" ({names})" if names else ""
        raise sec.error(key, f"must be finite and >= 0{axes}, got {raw!r}")
    return val


# ---- the laws ------------------------------------------------------------------------------------------------
def _limit(limit: float | None) -> float:
    """A law's `limit` for the kernels: NaN for none."""
    return math.nan if limit is None else float(limit)


def _gain_arrays(gains: AdmittanceGains) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return tuple(np.array(x, dtype=float) for x in (gains.kd, gains.kv, gains.ka))


def com_admittance(p_com: np.ndarray, v_com: np.ndarray, a_com: np.ndarray, cop_model: np.ndarray,
                   cop_measured: np.ndarray, gains: AdmittanceGains, dt: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Paper 004 Eq. 2: the CoM reference (3,) position [m], velocity [m/s], acceleration [m/s^2] corrected in
    x-y by the CoP difference `cop_model - cop_measured` (2,) [m]; z passes through (`_kernels.com_admittance`)."""
    out = np.empty((3, 3))
    _k.com_admittance(*(np.asarray(x, float) for x in (p_com, v_com, a_com)),
                      float(cop_model[0] - cop_measured[0]), float(cop_model[1] - cop_measured[1]),
                      *_gain_arrays(gains), _limit(gains.limit), float(dt), out)
    return out[0], out[1], out[2]


def ankle_admittance(R_world_sole: np.ndarray, cop_sole: np.ndarray, gains: AdmittanceGains) -> np.ndarray:
    """Paper 004 Eq. 3 (position part): the sole orientation reference tilted so that the measured CoP
    `cop_sole` (2,) [m], in the sole frame relative to the sole centre, goes to the centre:
    pitch = -kd_pitch c_x, roll = +kd_roll c_y (rad), applied about the sole's own axes
    (`_kernels.ankle_admittance`)."""
    out = np.empty((3, 3))
    _k.ankle_admittance(np.asarray(R_world_sole, float), float(cop_sole[0]), float(cop_sole[1]), float(gains.kd[0]),
                        float(gains.kd[1]), _limit(gains.limit), out)
    return out


def foot_force_difference(f_model: tuple[float, float], f_measured: tuple[float, float],
                          gains: AdmittanceGains, dt: float) -> tuple[float, float, float]:
    """Paper 004 Eq. 4-5 (signed difference, Kajita 2010): torso roll offset [rad], roll rate [rad/s] and roll
    acceleration [rad/s^2] references from the (left, right) normal forces [N] of the model and measured."""
    D = (f_model[0] - f_model[1]) - (f_measured[0] - f_measured[1])
    roll = -gains.kd[0] * D
    if gains.limit is not None and abs(roll) > gains.limit:
        roll = roll * (gains.limit / abs(roll))
    return roll, -gains.kv[0] * D / dt, -gains.ka[0] * D / dt**2


def zmp_distributor(p_zmp: np.ndarray, p_left: np.ndarray, p_right: np.ndarray, mass: float,
                    gravity: float = GRAVITY) -> tuple[dict[Side, np.ndarray], float]:
    """Paper 004 Eq. 6 (Kajita et al. 2010): per-foot target wrenches (6,) [N, N m] (ground on robot, world
    axes, about the sole centre `p_left` / `p_right` (3,)) realising the ZMP `p_zmp` (x, y) with both feet in
    contact; returns them and alpha (0: all on the left foot, 1: all on the right)."""
    pl, pr = np.asarray(p_left, float), np.asarray(p_right, float)
    p = np.array([p_zmp[0], p_zmp[1], 0.0])
    seg = (pr - pl)[:2]
    L2 = float(seg @ seg)
    alpha = float(np.clip((p[:2] - pl[:2]) @ seg / L2, 0.0, 1.0)) if L2 > 0 else 0.5
    f = {Side.LEFT: (1.0 - alpha) * mass * gravity, Side.RIGHT: alpha * mass * gravity}
    pos = {Side.LEFT: pl, Side.RIGHT: pr}
    tau0 = np.zeros(2)
    for s in Side:
        r = p[:2] - pos[s][:2]
        tau0 += np.array([r[1] * f[s], -r[0] * f[s]])  # (p - p_i) x (0, 0, f_i), x and y
    out = {}
    for s in Side:
        share = f[s] / (mass * gravity)
        w = np.zeros(6)
        w[2] = f[s]
        w[4] = share * tau0[1]
        # the roll moment goes to the foot on the side it presses (left foot: positive tau_x loads its +y edge)
        loads_left = tau0[0] > 0.0
        w[3] = tau0[0] if (s is Side.LEFT) == loads_left else 0.0
        out[s] = w
    return out, alpha


def wrench_admittance(F: np.ndarray, F_desired: np.ndarray, gains: ZmpDistributorGains, dt: float,
                      previous_error: np.ndarray | None = None) -> np.ndarray:
    """Paper 004 Eq. 7: F* = F - kp (F - F^d) - kd d/dt (F - F^d), (6,) wrenches [N, N m]. The paper writes the
    derivative term as (F - F^d) / dt; here it is the finite difference of the error since the previous tick
    (`previous_error`, None: no derivative term), which is what a derivative gain means."""
    e = np.asarray(F, float) - np.asarray(F_desired, float)
    out = np.asarray(F, float) - np.asarray(gains.kp) * e
    if previous_error is not None:
        out = out - np.asarray(gains.kd) * (e - previous_error) / dt
    return out


# ---- the component ------------------------------------------------------------------------------------------
def low_pass_gain(cutoff_hz: float | None, dt: float) -> float:
    """The gain ``alpha`` of a first-order low-pass ``y += alpha (u - y)`` at `cutoff_hz` [Hz] sampled every `dt`
    [s] (1: no filter, for None). The stabilizer's filters are `_kernels.filter_measurement`."""
    return 1.0 if cutoff_hz is None else 1.0 - float(np.exp(-2 * np.pi * cutoff_hz * dt))


class _Measured:
    """The stabilizer's filtered measurement of a tick: the ZMP (x, y) [m, world] (NaN when unloaded), per loaded
    foot the CoP (2,) [m] in its sole frame from the sole centre, per foot the normal force [N]."""

    __slots__ = ("zmp", "cop_sole", "normal_force")

    def __init__(self, zmp: np.ndarray | None = None, cop_sole: dict | None = None,
                 normal_force: dict | None = None):
        self.zmp = np.full(2, np.nan) if zmp is None else zmp
        self.cop_sole = {} if cop_sole is None else cop_sole
        self.normal_force = {} if normal_force is None else normal_force


@dataclass
class _FeetBuffers:
    """The inputs and outputs of `_kernels.feet_measurement`, rows left, right."""

    foot_mass: np.ndarray
    foot_com: np.ndarray
    R_sensor: np.ndarray = field(default_factory=lambda: np.zeros((2, 3, 3)))
    p_sensor: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    f_sensor: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    m_sensor: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    R_sole: np.ndarray = field(default_factory=lambda: np.zeros((2, 3, 3)))
    p_sole: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    out: np.ndarray = field(default_factory=lambda: np.zeros((2, 4)))
    zmp: np.ndarray = field(default_factory=lambda: np.zeros(2))


@dataclass
class _CopBuffers:
    """The inputs of `_kernels.model_cop`, rows left, right."""

    R: np.ndarray = field(default_factory=lambda: np.zeros((2, 3, 3)))
    p: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    w: np.ndarray = field(default_factory=lambda: np.zeros((2, 6)))
    use: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=bool))


def measured_wrench(force_sensor: np.ndarray, torque_sensor: np.ndarray, R: np.ndarray, p: np.ndarray,
                    foot_mass: float, foot_com: np.ndarray, gravity: float = GRAVITY) -> tuple[np.ndarray, np.ndarray]:
    """The ground's wrench on a foot from its ankle F/T reading (the foot below the sensor removed), world axes,
    moment about the sensor origin: F = -R f_s + m g e_z, M = -R m_s - (R c) x (-m g e_z). The per-tick twin of
    `estimation.contact_wrench_from_ft` (same result, no validation or broadcasting)."""
    F = -(R @ force_sensor)
    mg = foot_mass * gravity
    F[2] += mg
    c = R @ foot_com
    M = -(R @ torque_sensor)
    M[0] += mg * c[1]
    M[1] -= mg * c[0]
    return F, M


def _moment_about(F: np.ndarray, M: np.ndarray, p: np.ndarray, height: float) -> tuple[float, float]:
    """x, y of the moment of (F, M about p) about the point (0, 0, height)."""
    rx, ry, rz = p[0], p[1], p[2] - height
    return M[0] + ry * F[2] - rz * F[1], M[1] + rz * F[0] - rx * F[2]


def split_to_local(wrenches: dict, feet: dict, centres: dict) -> dict[Side, np.ndarray]:
    """Per-foot wrenches (6,) in world axes about the sole centres -> the QP's variables: LOCAL sole frame, about
    the sole frame's origin."""
    out = {}
    for s, w in wrenches.items():
        R, c = feet[s].rotation, centres[s]
        f = w[:3]
        m_origin = w[3:] + cross(c - feet[s].translation, f)
        out[s] = np.concatenate([R.T @ f, R.T @ m_origin])
    return out


def reference_wrench_targets(com: np.ndarray, com_acc: np.ndarray | None, feet: dict, sole_center: np.ndarray,
                             mass: float) -> dict[Side, np.ndarray]:
    """F of Eq. 7: the wrenches that realise the reference ZMP (the cart-table ZMP of the CoM reference) with
    the feet in `feet` (side -> sole pose, the active contacts): Eq. 6 with both feet, the whole weight on one
    foot (ZMP at its sole centre) otherwise. LOCAL sole frame about its origin, as the QP's wrench variables."""
    if len(feet) == 2:  # zmp_distributor and split_to_local on _cart_table_zmp, compiled
        out = np.empty((2, 6))
        L, R = feet[Side.LEFT], feet[Side.RIGHT]
        reference_split(com, _ZERO3 if com_acc is None else com_acc, L.rotation, L.translation, R.rotation,
                        R.translation, sole_center, float(mass), GRAVITY, out)
        return {Side.LEFT: out[0], Side.RIGHT: out[1]}
    centres = {s: M.act(sole_center) for s, M in feet.items()}
    F = {s: np.array([0.0, 0.0, mass * GRAVITY, 0.0, 0.0, 0.0]) for s in feet}
    return split_to_local(F, feet, centres)


class TeleopStabilizer(Stabilizer):
    """The enabled strategies of a `TeleopStabilizerSpec` (task-set `stabilizer: {type: force}`).

    `correct(meas, refs, feedback)` returns the references with the CoM (Eq. 2) and the torso target (Eq. 4-5)
    corrected, the wrench targets F* (Eq. 6-7, `wrench_targets`) and the tilted contact poses (Eq. 3,
    `contact_poses`) of the active contacts. The model side comes from `ModelFeedback`: the QP wrenches and the
    contact placements of the previous tick, the contact and torso references at reset (the nominal poses).
    `log` holds, per tick: measured ZMP x y, model CoP x y, CoM correction x y [m], torso roll correction [rad],
    left/right ankle tilt norms [rad], alpha.
    """

    type = "force"
    LOG_LABELS = ("zmp_x", "zmp_y", "cop_model_x", "cop_model_y", "dcom_x", "dcom_y", "torso_roll",
                  "tilt_left", "tilt_right", "alpha")

    @classmethod
    def parse(cls, sec: Section) -> TeleopStabilizerSpec:
        return parse_teleop_stabilizer(sec)

    def __init__(self, robot, spec: TeleopStabilizerSpec, dt: float):
        self.robot = robot
        self.spec = spec
        self.dt = dt
        m = robot.model
        self.model = m
        self.data = m.createData()
        self.sensor_ids = {s: m.getFrameId(robot.profile.feet[s].ft_sensor_frame) for s in Side}
        self.sole_ids = {s: robot.sole_frame_id(s) for s in Side}
        self.feet = {s: FootMass(*robot.foot_below_sensor(s)) for s in Side}
        self._foot = {s: (float(f.mass), np.array(f.p_sensor_com, dtype=float)) for s, f in self.feet.items()}
        self._cop_buf = _CopBuffers()
        self._com_gains = None if spec.com_admittance is None else _gain_arrays(spec.com_admittance)
        self._com_limit = math.nan if spec.com_admittance is None else _limit(spec.com_admittance.limit)
        g = spec.ankle_admittance
        self._ankle_gains = None if g is None else (float(g.kd[0]), float(g.kd[1]), _limit(g.limit))
        g = spec.foot_force_difference
        self._torso_gains = None if g is None else (float(g.kd[0]), float(g.kv[0]), float(g.ka[0]), _limit(g.limit))
        self._fk = ForwardKinematics(m)
        self._fk_frames = self._fk.frame_arrays([*(self.sensor_ids[s] for s in Side), *(self.sole_ids[s] for s in Side)])
        self._frames_R, self._frames_t = np.zeros((4, 3, 3)), np.zeros((4, 3))
        self._buf = _FeetBuffers(np.array([self._foot[s][0] for s in Side]), np.array([self._foot[s][1] for s in Side]),
                                 R_sensor=self._frames_R[:2], p_sensor=self._frames_t[:2], R_sole=self._frames_R[2:],
                                 p_sole=self._frames_t[2:])
        self.sole_center = np.array([*robot.profile.sole.center, 0.0])
        self.mass = robot.mass
        self.log = np.full(len(self.LOG_LABELS), np.nan)
        self._clear()

    def _clear(self) -> None:
        self._filter_alpha = low_pass_gain(self.spec.cop_cutoff_hz, self.dt)
        self._filter_state = np.zeros(8)        # ZMP x y, left CoP x y, right CoP x y, left, right normal force
        self._filter_started = np.zeros(5, dtype=bool)
        self._contact_nominal: dict[Side, pin.SE3] = {}
        self._torso_nominal: pin.SE3 | None = None
        # their rotations and translations as arrays (an SE3's attributes are copies made at each access)
        self._contact_nominal_p: dict[Side, np.ndarray] = {}
        self._torso_nominal_arrays: tuple[np.ndarray, np.ndarray] | None = None
        self._nominal_R = np.tile(np.eye(3), (2, 1, 1))  # the contacts' nominal rotations, rows left, right
        self._tilt_R = np.zeros((2, 3, 3))                 # and this tick's tilted ones (Eq. 3)
        self._ankle_on = np.zeros(2, dtype=np.bool_)
        self._flags = np.zeros(5, dtype=np.int64)          # `_kernels.corrections`' account of the tick
        self._prev_error = {s: None for s in Side}
        self._zmp_measured = False
        self.log[:] = np.nan

    def reset(self, meas: Measurement, refs: References, feedback: ModelFeedback) -> None:
        """Forget the filters; the contact and torso references of `feedback` become the nominal poses."""
        self._clear()
        for s, ref in feedback.contact_references.items():
            self._contact_nominal[s] = pin.SE3(ref)
            self._contact_nominal_p[s] = ref.translation.copy()
            self._nominal_R[_SIDES.index(s)] = ref.rotation
        torso = feedback.task_references.get(self.spec.torso_task)
        if torso is not None:
            self._torso_nominal = pin.SE3(torso)
            self._torso_nominal_arrays = (torso.rotation.copy(), torso.translation.copy())

    # -------------------------------------------------------------- measurement
    @property
    def measured(self) -> _Measured:
        """The filtered measurement of the last tick (`_measure`)."""
        return self._measured_from(self._filter_state, self._zmp_measured)

    def _measure(self, meas: Measurement) -> bool:
        """Per-foot normal force and CoP (sole frame, from its centre) and the ZMP (world x y), low-passed,
        from the ankle F/T sensors on the measured configuration (the placements: `ForwardKinematics`, the
        arithmetic and the filters:
        `_kernels.feet_measurement` (`measured_wrench`, `_moment_about`) and `filter_measurement`), into the
        filters' state (`measured`); returns whether this tick's measurement gave a ZMP."""
        buf = self._buf
        state = self._filter_state
        if self._fk.supported:  # rows: the sensors', then the soles' frames (buf's views); one compiled call
            fk = self._fk
            ft_force, ft_torque = meas.ft_force, meas.ft_torque
            zmp_ok = _k.measure_feet(meas.q, fk._kinds, fk._parents, fk._idx_q, fk._R0, fk._t0, fk.R, fk.t,
                                     *self._fk_frames, self._frames_R, self._frames_t, ft_force[_LEFT], ft_force[_RIGHT],
                                     ft_torque[_LEFT], ft_torque[_RIGHT], buf.f_sensor, buf.m_sensor, buf.foot_mass,
                                     buf.foot_com, self.sole_center, self.spec.min_normal_force, GRAVITY, buf.out,
                                     buf.zmp, self._filter_alpha, state, self._filter_started)
            self._zmp_measured = zmp_ok
            return zmp_ok
        m, d = self.model, self.data  # other joint types: pinocchio's placements
        pin.forwardKinematics(m, d, meas.q)
        for i, s in enumerate(Side):
            M = pin.updateFramePlacement(m, d, self.sensor_ids[s])
            S = pin.updateFramePlacement(m, d, self.sole_ids[s])
            buf.R_sensor[i] = M.rotation
            buf.p_sensor[i] = M.translation
            buf.R_sole[i] = S.rotation
            buf.p_sole[i] = S.translation
        ft_force, ft_torque = meas.ft_force, meas.ft_torque
        buf.f_sensor[0] = ft_force[_LEFT]
        buf.f_sensor[1] = ft_force[_RIGHT]
        buf.m_sensor[0] = ft_torque[_LEFT]
        buf.m_sensor[1] = ft_torque[_RIGHT]
        zmp_ok = feet_measurement(buf.R_sensor, buf.p_sensor, buf.f_sensor, buf.m_sensor, buf.foot_mass,
                                  buf.foot_com, buf.R_sole, buf.p_sole, self.sole_center, self.spec.min_normal_force,
                                  GRAVITY, buf.out, buf.zmp)
        filter_measurement(buf.out, buf.zmp, zmp_ok, self._filter_alpha, state, self._filter_started)
        self._zmp_measured = zmp_ok
        return zmp_ok

    def _measured_from(self, state: np.ndarray, zmp_ok: bool) -> _Measured:
        f = state.tolist()
        loaded = self._buf.out[:, 3].tolist()
        cop = {}
        if loaded[0] != 0.0:
            cop[_LEFT] = state[2:4].copy()
        if loaded[1] != 0.0:
            cop[_RIGHT] = state[4:6].copy()
        return _Measured(state[0:2].copy() if zmp_ok else None, cop, {_LEFT: f[6], _RIGHT: f[7]})

    def model_cop(self, feedback: ModelFeedback) -> np.ndarray | None:
        """ZMP (x, y) of the model's QP wrenches of the last tick, world frame; None when unloaded
        (`_kernels.model_cop`)."""
        buf = self._model_side(feedback)
        out = np.empty(2)
        return out if _k.model_cop(buf.R, buf.p, buf.w, buf.use, out) else None

    def _model_side(self, feedback: ModelFeedback) -> _CopBuffers:
        """`model_cop`'s inputs from the feedback: the active contacts' placements and wrenches."""
        buf = self._cop_buf
        use = buf.use
        poses, wrenches, active = feedback.contact_poses, feedback.wrenches, feedback.active
        for i, s in enumerate(_SIDES):
            M = poses.get(s)
            w = wrenches.get(s)
            use[i] = M is not None and w is not None and s in active
            if use[i]:
                buf.R[i] = M.rotation
                buf.p[i] = M.translation
                buf.w[i] = w
        return buf

    # -------------------------------------------------------------- the corrections
    def correct(self, meas: Measurement, refs: References, feedback: ModelFeedback) -> References:
        spec, dt = self.spec, self.dt
        measured_zmp = self._measure(meas)
        state = self._filter_state
        # the model's side (`model_cop`'s inputs) and which laws apply, then the laws in one call
        # (`_kernels.corrections`)
        buf = self._model_side(feedback)
        wrenches, active = feedback.wrenches, feedback.active
        both = _LEFT in active and _RIGHT in active
        targets = refs.targets
        com_ref = refs.com
        com_on = self._com_gains is not None and com_ref is not None
        com_out = np.empty((3, 3))
        if com_on:
            com_p, com_v, com_a = com_ref.position, com_ref.velocity, com_ref.acceleration
            com_kd, com_kv, com_ka = self._com_gains
        else:
            com_p = com_v = com_a = com_kd = com_kv = com_ka = _ZERO3
        torso_on = self._torso_gains is not None and self._torso_nominal is not None and both
        R_torso, w_torso, a_torso = np.empty((3, 3)), np.empty(6), np.empty(6)
        if torso_on:
            base = targets.get(spec.torso_task)
            R_nominal, p_nominal = self._torso_nominal_arrays
            if base is not None:
                p0, R0 = base.position, (base.rotation if base.rotation is not None else R_nominal)
            else:
                p0, R0 = p_nominal, R_nominal
            torso_gains = self._torso_gains
        else:
            R0, torso_gains = _EYE3, _NO_TORSO
        ankle = self._ankle_gains
        ankle_on = self._ankle_on
        nominal = self._contact_nominal
        for i, s in enumerate(_SIDES):
            ankle_on[i] = ankle is not None and s in nominal and s in active
        kd_x, kd_y, ankle_limit = ankle if ankle is not None else _NO_ANKLE
        flags, log = self._flags, self.log
        _k.corrections(state, self._buf.out[:, 3], measured_zmp, buf.R, buf.p, buf.w, buf.use, com_on, com_p, com_v, com_a,
                       com_kd, com_kv, com_ka, self._com_limit, dt, com_out, torso_on, wrenches.get(_LEFT, _ZERO6),
                       wrenches.get(_RIGHT, _ZERO6), *torso_gains, R0, R_torso, w_torso, a_torso, ankle_on,
                       self._nominal_R, kd_x, kd_y, ankle_limit, self._tilt_R, log, flags)
        if flags[1]:  # Eq. 2
            com_ref = PointReference.unchecked(com_out[0], com_out[1], com_out[2])  # the kernel's finite (3,) rows
        if flags[2]:  # Eq. 4-5
            targets = dict(targets)
            targets[spec.torso_task] = PoseReference.unchecked(np.array(p0, dtype=np.float64), R_torso, w_torso,
                                                               a_torso)
        # Eq. 6-7
        wrench_targets = refs.wrench_targets
        z = spec.zmp_distributor
        if z is not None and both and flags[0] and com_ref is not None:
            feet = {s: self._contact_nominal.get(s, feedback.contact_references.get(s)) for s in Side}
            centre = {s: feet[s].act(self.sole_center) for s in Side}
            p_ref = _cart_table_zmp(com_ref.position, com_ref.acceleration, centre)
            F, _ = zmp_distributor(p_ref, centre[Side.LEFT], centre[Side.RIGHT], self.mass)
            Fd, alpha = zmp_distributor(state[0:2].copy(), centre[Side.LEFT], centre[Side.RIGHT], self.mass)
            star = {}
            for s in Side:
                star[s] = wrench_admittance(F[s], Fd[s], z, dt, self._prev_error[s])
                self._prev_error[s] = F[s] - Fd[s]
            wrench_targets = split_to_local(star, feet, centre)
            log[9] = alpha
        # Eq. 3: each loaded, active contact's reference tilted from its nominal pose
        contact_poses = refs.contact_poses
        if ankle is not None:
            contact_poses = dict(contact_poses)
            for i, s in enumerate(_SIDES):
                how = flags[3 + i]
                if how == 1:
                    contact_poses[s] = nominal[s]
                elif how == 2:
                    contact_poses[s] = PoseReference.unchecked(self._contact_nominal_p[s], self._tilt_R[i].copy(),
                                                               _ZERO6, _ZERO6)
        if (com_ref is refs.com and targets is refs.targets and wrench_targets is refs.wrench_targets
                and contact_poses is refs.contact_poses):
            return refs
        return refs.corrected(com_ref, targets, wrench_targets, contact_poses)


def _cart_table_zmp(com: np.ndarray, com_acc: np.ndarray | None, centre: dict) -> np.ndarray:
    ground = min(c[2] for c in centre.values())
    a = np.zeros(3) if com_acc is None else com_acc
    h = com[2] - ground
    return com[:2] - h / GRAVITY * a[:2]
