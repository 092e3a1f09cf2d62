"""What flows between the simulator (or a real robot), the controllers and the recorder."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .robots import Side


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
    """

    t: float
    q: np.ndarray
    v: np.ndarray
    imu_quat: np.ndarray
    gyro: np.ndarray
    accelerometer: np.ndarray
    ft_force: dict[Side, np.ndarray] = field(default_factory=dict)
    ft_torque: dict[Side, np.ndarray] = field(default_factory=dict)


@dataclass
class Command:
    """A joint-space command for the actuated joints (pinocchio order), used according to the actuation mode.

    tau: (na,) [N m] torques (torque mode; feed-forward in position mode if given).
    q, v: (na,) position [rad] and velocity [rad/s] references (position and SPD modes).
    """

    tau: np.ndarray | None = None
    q: np.ndarray | None = None
    v: np.ndarray | None = None


@dataclass
class References:
    """What a scenario (planner, teleoperation source) asks for at one tick. Unused fields stay None.

    contacts: feet that should be in contact.
    com, com_vel, com_acc: (3,) CoM reference [m, m/s, m/s^2], world frame.
    feet: per swinging/moving foot, (position (3,), velocity (3,), acceleration (3,)) of the sole frame origin
        in the world; orientation held at its current/start value unless `feet_rotation` gives it.
    zmp: (3,) planned ZMP [m], world frame (walking scenarios).
    targets: references for the controller's named frame tasks (e.g. teleoperation hands and head):
        task name -> pin.SE3, or (pin.SE3, velocity (6,), acceleration (6,)) in LOCAL_WORLD_ALIGNED axes.
    """

    t: float
    contacts: frozenset = frozenset({Side.LEFT, Side.RIGHT})
    com: np.ndarray | None = None
    com_vel: np.ndarray | None = None
    com_acc: np.ndarray | None = None
    feet: dict = field(default_factory=dict)
    feet_rotation: dict = field(default_factory=dict)
    zmp: np.ndarray | None = None
    targets: dict = field(default_factory=dict)
