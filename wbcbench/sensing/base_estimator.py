"""A floating-base estimator from what a real robot has: the IMU's orientation and rate, the joint encoders and the
ankle F/T sensors (leg kinematics anchored on the loaded feet).

Orientation: R_world_base = R_world_imu R_base_imu^T, the IMU's own orientation estimate (with its drift) and the
IMU's rotation in the base from the encoders (TALOS' IMU sits in the torso, behind two torso joints).
Position: with that orientation and the encoder angles, forward kinematics give each sole relative to the base;
each loaded foot (F/T normal force above `load_threshold`) is anchored where it touched down (the estimate of its
position at the tick it became loaded), and the base is placed so that the loaded feet stay on their anchors
(weighted by their normal forces). Linear velocity: the position estimate differentiated and low-passed;
angular velocity: the gyro minus the rate of the IMU's rotation in the base (from the encoders), in base axes. Starts from the first measurement's base pose (a robot starts from a
known, calibrated pose).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..side import Side
from ..estimation.feet import FeetSensing
from ..types import Measurement

__all__ = ["BaseEstimator"]



class BaseEstimator:
    """Estimates the base pose and twist (pinocchio conventions: LOCAL base velocity) from the sensors."""

    def __init__(self, robot, dt: float, *, load_threshold: float = 50.0, velocity_cutoff_hz: float = 20.0):
        self.robot = robot
        self.dt = dt
        self.load_threshold = load_threshold
        m = robot.model
        self.model, self.data = m, m.createData()
        self.feet = FeetSensing(robot)
        self.imu_id = m.getFrameId(robot.profile.imu_frame)
        self.alpha = 1.0 - math.exp(-2.0 * math.pi * velocity_cutoff_hz * dt)
        self._q = pin.neutral(m)
        self.reset()

    def reset(self) -> None:
        self.p = None
        self.v_world = np.zeros(3)
        self.anchor: dict[Side, np.ndarray] = {}
        self.loaded = {s: False for s in Side}
        self._R_base_imu_prev = None

    def estimate(self, meas: Measurement) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) with the estimated base, the measurement's joints."""
        m, d = self.model, self.data
        q = self._q  # the base at the origin, unrotated: frames in base coordinates
        q[7:] = meas.q[7:]
        pin.framesForwardKinematics(m, d, q)
        R_base_imu = d.oMf[self.imu_id].rotation.copy()
        x, y, z, w = meas.imu_quat
        R = pin.Quaternion(w, x, y, z).toRotationMatrix() @ R_base_imu.T
        rel = {s: R @ d.oMf[self.feet.sole_ids[s]].translation for s in Side}
        if self.p is None:  # the known starting pose
            self.p = meas.q[:3].copy()
            for s in Side:
                self.anchor[s] = self.p + rel[s]
        fz = self.feet.vertical_forces(meas, d, R)
        p_prev = self.p
        num, den = np.zeros(3), 0.0
        for s in Side:
            loaded = fz[s] > self.load_threshold
            if loaded and not self.loaded[s]:  # touch-down: anchored where the estimate puts it
                self.anchor[s] = p_prev + rel[s]
            self.loaded[s] = loaded
            if loaded:
                num += fz[s] * (self.anchor[s] - rel[s])
                den += fz[s]
        p = num / den if den > 0.0 else p_prev + self.v_world * self.dt
        self.v_world += self.alpha * ((p - p_prev) / self.dt - self.v_world)
        self.p = p
        q_out = meas.q.copy()
        q_out[:3] = p
        q_out[3:7] = pin.Quaternion(R).coeffs()
        v_out = meas.v.copy()
        v_out[:3] = R.T @ self.v_world
        # gyro: the IMU's rate in the world, in IMU axes; less the IMU's rate relative to the base (torso joints)
        prev = self._R_base_imu_prev if self._R_base_imu_prev is not None else R_base_imu
        w_rel = pin.log3(prev.T @ R_base_imu) / self.dt
        v_out[3:6] = R_base_imu @ (meas.gyro - w_rel)
        self._R_base_imu_prev = R_base_imu
        return q_out, v_out

    @staticmethod
    def error(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
        """(6,) base error: position [m] (world) and orientation log3(R_true^T R_est) [rad] (base axes)."""
        out = np.empty(6)
        out[:3] = q_est[:3] - q_true[:3]
        Rt = pin.Quaternion(q_true[6], *q_true[3:6]).toRotationMatrix()
        Re = pin.Quaternion(q_est[6], *q_est[3:6]).toRotationMatrix()
        out[3:] = pin.log3(Rt.T @ Re)
        return out
