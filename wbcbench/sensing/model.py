"""The sensor model: the simulator's perfect measurement in, what the controller sees out (see `SensorProfile`)."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import replace

import numpy as np
import pinocchio as pin

from ..side import Side
from ..types import Measurement
from .base_estimator import BaseEstimator
from .profile import SensorProfile, load_sensor_profile

__all__ = ["SensorModel", "make_sensor_model"]


class SensorModel:
    """Applies a `SensorProfile` tick by tick, with its own seeded random state (runs are reproducible).

    `measure(true)` returns the controller's measurement; `base_error(q_true)` the last base estimate's error
    (NaN when the base is not estimated). An ideal profile returns the simulator's measurement itself.
    """

    def __init__(self, profile: SensorProfile, robot, dt: float, seed: int = 0):
        self.profile = profile
        self.robot = robot
        self.dt = dt
        self.seed = seed
        self.ideal = profile.ideal
        self.delay = int(round(profile.latency / dt))
        self.estimator = BaseEstimator(robot, dt) if profile.base == "estimated" else None
        self.beta = 1.0 - math.exp(-2.0 * math.pi * profile.velocity_cutoff_hz * dt)
        self.reset()

    def reset(self) -> None:
        p = self.profile
        rng = self.rng = np.random.default_rng(self.seed)
        self.ft_bias = {s: np.concatenate([rng.normal(0.0, p.force_bias, 3), rng.normal(0.0, p.torque_bias, 3)])
                        for s in Side}
        self.ft_drift = {s: np.zeros(3) for s in Side}
        self.gyro_bias = rng.normal(0.0, p.gyro_bias, 3)
        self.accel_bias = rng.normal(0.0, p.accel_bias, 3)
        self.yaw_error = 0.0
        # calibration offsets from a generator of their own, so that a profile without them draws as before
        self.encoder_offset = (np.random.default_rng([self.seed, 1]).normal(0.0, p.encoder_offset, len(self.robot.joint_names))
                               if p.encoder_offset else None)
        self._q_prev = None
        self._v_fd = None
        self._line: deque = deque()
        self._last: Measurement | None = None
        self.n_dropped = 0
        self._error = np.full(6, np.nan)
        if self.estimator is not None:
            self.estimator.reset()

    # ------------------------------------------------------------------ one tick
    def measure(self, true: Measurement) -> Measurement:
        if self.ideal:
            return true
        sensed = self._corrupt(true)
        if self.estimator is not None:
            q, v = self.estimator.estimate(sensed)
            sensed = replace(sensed, q=q, v=v)
            self._error = BaseEstimator.error(q, true.q)
        self._line.append(sensed)
        out = self._line.popleft() if len(self._line) > self.delay else self._line[0]
        if self._last is not None and self.profile.drop_rate > 0 and self.rng.random() < self.profile.drop_rate:
            out = self._last
            self.n_dropped += 1
        self._last = out
        return replace(out, t=true.t) if out.t != true.t else out

    def base_error(self) -> np.ndarray:
        """(6,) position [m] and orientation [rad] error of the last base estimate (NaN without an estimator)."""
        return self._error

    def _corrupt(self, m: Measurement) -> Measurement:
        p, rng, dt = self.profile, self.rng, self.dt
        ft_force, ft_torque = {}, {}
        for s in Side:
            if p.force_drift:
                self.ft_drift[s] += rng.normal(0.0, p.force_drift * math.sqrt(dt), 3)
            b = self.ft_bias[s]
            ft_force[s] = m.ft_force[s] + b[:3] + self.ft_drift[s] + rng.normal(0.0, p.force_noise, 3)
            ft_torque[s] = m.ft_torque[s] + b[3:] + rng.normal(0.0, p.torque_noise, 3)
        gyro = m.gyro + self.gyro_bias + rng.normal(0.0, p.gyro_noise, 3)
        accel = m.accelerometer + self.accel_bias + rng.normal(0.0, p.accel_noise, 3)
        quat = m.imu_quat
        if p.orientation_noise or p.yaw_drift:
            self.yaw_error += rng.normal(0.0, p.yaw_drift * math.sqrt(dt))
            x, y, z, w = quat
            R = pin.Quaternion(w, x, y, z).toRotationMatrix()
            tilt = np.array([*rng.normal(0.0, p.orientation_noise, 2), 0.0])
            R = pin.exp3(np.array([0.0, 0.0, self.yaw_error])) @ R @ pin.exp3(tilt)
            quat = pin.Quaternion(R).coeffs().copy()  # x, y, z, w
        q = m.q.copy()
        if self.encoder_offset is not None:
            q[7:] += self.encoder_offset
        if p.encoder_resolution:
            res = p.encoder_resolution
            q[7:] = np.round(q[7:] / res) * res
        v = m.v
        if p.joint_velocity == "finite_difference":
            v = v.copy()
            if self._q_prev is None:
                self._v_fd = np.zeros(len(q) - 7)
            else:
                self._v_fd += self.beta * ((q[7:] - self._q_prev) / dt - self._v_fd)
            v[6:] = self._v_fd
            self._q_prev = q[7:].copy()
        return Measurement(t=m.t, q=q, v=v, imu_quat=quat, gyro=gyro, accelerometer=accel, ft_force=ft_force,
                           ft_torque=ft_torque, tau=m.tau)


def make_sensor_model(profile: SensorProfile | str | None, robot, dt: float, seed: int = 0) -> SensorModel:
    """A sensor model from a profile, a profile name or file (None: ideal)."""
    if profile is None:
        profile = SensorProfile()
    elif not isinstance(profile, SensorProfile):
        profile = load_sensor_profile(profile)
    return SensorModel(profile, robot, dt, seed)
