"""What flows between the simulator (or a real robot), the controllers and the recorder."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from .side import Side

#: standard gravity [m/s^2], the magnitude every model, planner, estimator and metric uses (the simulator's gravity
#: vector is (0, 0, -GRAVITY))
GRAVITY = 9.81


class ActuationMode(str, Enum):
    """How joint commands reach the simulated robot.

    TORQUE: motors, the command is joint torque (clamped to the URDF effort limits).
    POSITION: MuJoCo position servos, torque = kp (q_ref - q) + kd (v_ref - v), with the profile's
        `position_gains`; the damping is integrated implicitly (integrator implicitfast).
    SPD: stable PD (Tan, Liu and Turk 2011): torque = kp (q_ref - q - dt v) + kd (v_ref - v - dt a), with
        the next acceleration a predicted from the full mass matrix, same gains as POSITION.
    """

    TORQUE = "torque"
    POSITION = "position"
    SPD = "spd"


@dataclass
class Measurement:
    """What a real robot would give a controller at one control tick.

    q: (nq,) pinocchio configuration: base pose from the base estimator, joints from the encoders.
    v: (nv,) pinocchio velocity: base twist (LOCAL frame) from the estimator, joint velocities from encoders.
    imu_quat: (4,) orientation of the IMU frame in the world, (x, y, z, w).
    gyro: (3,) [rad/s] and accelerometer: (3,) [m/s^2] in the IMU frame.
    ft_force / ft_torque: per foot (3,) [N], [N m], the ankle F/T sensor reading in the sensor frame: the
        wrench the leg above exerts on the foot below, about the sensor origin (MuJoCo's convention). Standing
        still, the ground contact force is F = -R F_s - m_foot g.
    tau: (na,) [N m] the joint torque sensors' reading (pinocchio joint order), or None when the robot gives none.
        The MuJoCo simulator gives the actuators' output torque at the motor side of each joint (after a torque
        loop's delay and lag; friction and rotor inertia not subtracted); the sensor layer passes it unchanged.
    """

    t: float
    q: np.ndarray
    v: np.ndarray
    imu_quat: np.ndarray
    gyro: np.ndarray
    accelerometer: np.ndarray
    ft_force: dict[Side, np.ndarray] = field(default_factory=dict)
    ft_torque: dict[Side, np.ndarray] = field(default_factory=dict)
    tau: np.ndarray | None = None


@dataclass
class Command:
    """A joint-space command for the actuated joints (pinocchio order), used according to the actuation mode.

    tau: (na,) [N m] torques (torque mode; feed-forward in position mode if given).
    q, v: (na,) position [rad] and velocity [rad/s] references (position and SPD modes).
    """

    tau: np.ndarray | None = None
    q: np.ndarray | None = None
    v: np.ndarray | None = None


def _frozen_vector(value, n: int, what: str) -> np.ndarray:
    """A read-only float (n,) array of `value` (no copy when it already is one)."""
    a = value if type(value) is np.ndarray and value.dtype == np.float64 else np.asarray(value, dtype=np.float64)
    if a.shape != (n,):
        raise ValueError(f"{what} must have shape ({n},), got {a.shape}")
    return a


_ZERO3 = np.zeros(3)
_ZERO6 = np.zeros(6)
_ZERO3.flags.writeable = False
_ZERO6.flags.writeable = False


@dataclass(frozen=True, slots=True)
class PointReference:
    """A point's reference in the world frame (e.g. the CoM): position [m], velocity [m/s], acceleration
    [m/s^2], each (3,). Velocity and acceleration default to zero (a shared read-only array)."""

    position: np.ndarray
    velocity: np.ndarray = None  # type: ignore[assignment]  (None: zero)
    acceleration: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self):
        setattr_ = object.__setattr__
        setattr_(self, "position", _frozen_vector(self.position, 3, "PointReference.position"))
        setattr_(self, "velocity", _ZERO3 if self.velocity is None else
                 _frozen_vector(self.velocity, 3, "PointReference.velocity"))
        setattr_(self, "acceleration", _ZERO3 if self.acceleration is None else
                 _frozen_vector(self.acceleration, 3, "PointReference.acceleration"))

    @classmethod
    def unchecked(cls, position: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray) -> "PointReference":
        """From (3,) float64 arrays already checked (e.g. rows of a precomputed plan): no conversion, no copy."""
        ref = _new(cls)
        _POINT_SET[0](ref, position)
        _POINT_SET[1](ref, velocity)
        _POINT_SET[2](ref, acceleration)
        return ref


@dataclass(frozen=True, slots=True)
class JointReference:
    """A joint-space reference for a posture task (`References.targets[task name]`): the full configuration
    `configuration` (nq,) of which the task uses its selected joints (the base part may hold anything normalized),
    and the task axes' velocity and acceleration (dim,) [rad/s, rad/s^2] (None: zero)."""

    configuration: np.ndarray
    velocity: np.ndarray | None = None
    acceleration: np.ndarray | None = None


@dataclass(frozen=True, slots=True)
class PoseReference:
    """A frame's SE(3) reference in the world: position (3,) [m], rotation (3, 3) or None, and the twist
    velocity (6,) [m/s, rad/s] and acceleration (6,) in LOCAL_WORLD_ALIGNED axes (linear first).

    `rotation` None means "hold the orientation the frame's task has" (a swing foot that only translates).
    Velocity and acceleration default to zero."""

    position: np.ndarray
    rotation: np.ndarray | None = None
    velocity: np.ndarray = None  # type: ignore[assignment]  (None: zero)
    acceleration: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self):
        setattr_ = object.__setattr__
        setattr_(self, "position", _frozen_vector(self.position, 3, "PoseReference.position"))
        if self.rotation is not None:
            R = np.asarray(self.rotation, dtype=np.float64)
            if R.shape != (3, 3):
                raise ValueError(f"PoseReference.rotation must have shape (3, 3), got {R.shape}")
            setattr_(self, "rotation", R)
        setattr_(self, "velocity", _ZERO6 if self.velocity is None else
                 _frozen_vector(self.velocity, 6, "PoseReference.velocity"))
        setattr_(self, "acceleration", _ZERO6 if self.acceleration is None else
                 _frozen_vector(self.acceleration, 6, "PoseReference.acceleration"))

    @classmethod
    def from_se3(cls, pose, velocity=None, acceleration=None) -> "PoseReference":
        """From a `pinocchio.SE3` (copied)."""
        return cls(pose.translation.copy(), pose.rotation.copy(), velocity, acceleration)

    @classmethod
    def unchecked(cls, position: np.ndarray, rotation: np.ndarray | None, velocity: np.ndarray,
                  acceleration: np.ndarray) -> "PoseReference":
        """From float64 arrays of the right shapes already checked ((3,), (3, 3) or None, (6,), (6,); e.g. rows
        of a precomputed plan): no conversion, no copy."""
        ref = _new(cls)
        _POSE_SET[0](ref, position)
        _POSE_SET[1](ref, rotation)
        _POSE_SET[2](ref, velocity)
        _POSE_SET[3](ref, acceleration)
        return ref

    @classmethod
    def translating(cls, position, velocity=None, acceleration=None, rotation=None) -> "PoseReference":
        """A frame moving its origin (linear velocity / acceleration (3,) [m/s, m/s^2]); orientation `rotation`
        (3, 3), or None to hold the task's."""
        v = None if velocity is None else np.concatenate((velocity, _ZERO3))
        a = None if acceleration is None else np.concatenate((acceleration, _ZERO3))
        return cls(position, rotation, v, a)


@dataclass(frozen=True, slots=True)
class References:
    """What a scenario (planner, teleoperation source) asks for at one tick, and what stabilizers correct.
    Unused fields stay None / empty.

    contacts: feet that should be in contact.
    com: the CoM reference (world frame).
    zmp: (3,) planned ZMP [m], world frame (walking scenarios).
    feet: per swinging/moving foot, the sole frame's reference (`PoseReference`, rotation None: held).
    targets: references of the controller's named frame tasks (e.g. teleoperation hands, head, torso).
    wrench_targets: per contact, a (6,) wrench the inverse-dynamics QP regularises the contact wrench towards
        [N, N m], LOCAL sole frame at its origin, exerted by the ground (e.g. the force-based stabilizer's
        Eq. 6-7 split); empty: no target.
    contact_poses: per active contact, the reference pose of the contact (world; a `pinocchio.SE3`, or a
        `PoseReference` whose position and rotation are used: no SE3 made per tick) replacing the
        one it took at touch-down (e.g. the ankle admittance's tilt, Eq. 3); empty: keep it.
    lift_off: per foot in contact, the time [s] (the clock of `t`) of its next planned lift-off: the plan's
        contact schedule ahead, so that a controller can unload a leaving foot before it leaves; empty: none
        planned (or the scenario has no plan).
    swing_pitch: per swinging foot, a (3,) [delta, delta_dot, delta_ddot] [rad, rad/s, rad/s^2]: a pitch about the
        sole's lateral axis the plan offers on top of `feet`' rotation, shaped so that the swing ankle accelerates
        less (`wbcbench.planning.swing_pitch`; zero at lift-off and touch-down); a controller takes it only when its
        task set asks for it; empty: none offered. With a walk's `toe_off`, (4,) [delta, delta_dot, delta_ddot,
        x]: the pitch is about the sole's edge at x [m] in the sole frame (its toe), and a foot still in contact
        has one in its roll about that edge before its lift-off.
    """

    t: float
    contacts: frozenset = frozenset({Side.LEFT, Side.RIGHT})
    com: PointReference | None = None
    zmp: np.ndarray | None = None
    feet: dict = field(default_factory=dict)
    targets: dict = field(default_factory=dict)
    wrench_targets: dict = field(default_factory=dict)
    contact_poses: dict = field(default_factory=dict)
    lift_off: dict = field(default_factory=dict)
    swing_pitch: dict = field(default_factory=dict)

    @classmethod
    def planned(cls, t: float, contacts: frozenset, com: PointReference | None, zmp: np.ndarray | None,
                feet: dict, targets: dict | None = None, lift_off: dict | None = None,
                swing_pitch: dict | None = None) -> "References":
        """A tick of a plan from values already checked (no stabilizer fields): as the constructor, without its
        per-field machinery (a walk or a teleoperation source makes one every tick)."""
        return _references(t, contacts, com, zmp, feet, {} if targets is None else targets, {}, {},
                           _NONE_AHEAD if lift_off is None else lift_off,
                           _NONE_AHEAD if swing_pitch is None else swing_pitch)

    def corrected(self, com: PointReference | None, targets: dict, wrench_targets: dict,
                  contact_poses: dict, feet: dict | None = None) -> "References":
        """A copy with the fields a stabilizer corrects replaced, and the feet's when given (`dataclasses.replace`
        without its per-field machinery: a stabilizer does this every tick)."""
        return _references(self.t, self.contacts, com, self.zmp, self.feet if feet is None else feet, targets,
                           wrench_targets, contact_poses, self.lift_off, self.swing_pitch)

    def missing(self, names) -> list[str]:
        """The fields among `names` this tick leaves unset (None or empty)."""
        out = []
        for n in names:
            v = getattr(self, n)
            if v is None or (isinstance(v, (dict, frozenset)) and not v):
                out.append(n)
        return out


# the fast constructors set the slots of these frozen classes through their descriptors (what the dataclass
# __init__ does through object.__setattr__, by name)
_new = object.__new__
_POINT_SET = tuple(PointReference.__dict__[n].__set__ for n in ("position", "velocity", "acceleration"))
_POSE_SET = tuple(PoseReference.__dict__[n].__set__ for n in ("position", "rotation", "velocity", "acceleration"))
_REFERENCE_SET = tuple(References.__dict__[n].__set__ for n in ("t", "contacts", "com", "zmp", "feet", "targets",
                                                                "wrench_targets", "contact_poses", "lift_off",
                                                                "swing_pitch"))
_NONE_AHEAD: dict = {}  # shared by the references without a schedule ahead or a swing pitch (never written)


def _references(t, contacts, com, zmp, feet, targets, wrench_targets, contact_poses, lift_off,
                swing_pitch) -> References:
    """A `References` of these fields (`References.planned`, `References.corrected`), set slot by slot."""
    new = _new(References)
    (t_, contacts_, com_, zmp_, feet_, targets_, wrench_targets_, contact_poses_, lift_off_,
     swing_pitch_) = _REFERENCE_SET
    t_(new, t)
    contacts_(new, contacts)
    com_(new, com)
    zmp_(new, zmp)
    feet_(new, feet)
    targets_(new, targets)
    wrench_targets_(new, wrench_targets)
    contact_poses_(new, contact_poses)
    lift_off_(new, lift_off)
    swing_pitch_(new, swing_pitch)
    return new


@dataclass(frozen=True, slots=True)
class ModelFeedback:
    """What a controller tells its stabilizer about its own model at a tick (a stabilizer reads nothing else of
    the controller).

    q: (nq,) the model's configuration (the integrated one in position mode, the measured one in torque mode).
    active: the contacts the model holds.
    wrenches: per side, the (6,) contact wrench of the last solve [N, N m], LOCAL sole frame (zeros if none).
    contact_poses: per active contact, the world placement of the contact frame at the last solve (SE3).
    contact_references: per contact, its current reference pose (SE3; absent before the first touch-down).
    task_references: the controller's frame-task references by task name (SE3), e.g. the torso's.
    """

    q: np.ndarray
    active: frozenset = frozenset()
    wrenches: dict = field(default_factory=dict)
    contact_poses: dict = field(default_factory=dict)
    contact_references: dict = field(default_factory=dict)
    task_references: dict = field(default_factory=dict)

    @classmethod
    def of_tick(cls, q: np.ndarray, active: frozenset, wrenches: dict | None = None,
                contact_poses: dict | None = None) -> "ModelFeedback":
        """A tick's feedback (the references are given at reset only), as the constructor without its per-field
        machinery (a controller makes one every tick); the fields not given are new empty dicts."""
        new = _new(cls)
        q_, active_, wrenches_, poses_, contact_refs_, task_refs_ = _MODEL_FEEDBACK_SET
        q_(new, q)
        active_(new, active)
        wrenches_(new, {} if wrenches is None else wrenches)
        poses_(new, {} if contact_poses is None else contact_poses)
        contact_refs_(new, {})
        task_refs_(new, {})
        return new


_MODEL_FEEDBACK_SET = tuple(ModelFeedback.__dict__[n].__set__ for n in ("q", "active", "wrenches", "contact_poses",
                                                                       "contact_references", "task_references"))
