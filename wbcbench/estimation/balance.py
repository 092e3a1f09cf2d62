"""What a position-controlled humanoid's balance stabilizer needs, estimated from a robot's sensors:
the ZMP measured by the ankle F/T sensors, and the CoM (position, velocity) anchored on the support foot.

Anchoring (as the TALOS balance stack does, SIM-NOTES "Position mode"): on soft contacts the whole robot rocks
on its feet while the joints track their references, and feeding that rocking back through a world-frame CoM
diverges. The CoM is therefore computed from the measured joint angles with the robot placed so that its loaded
feet sit exactly where the controller's model puts them (one correction per foot, averaged with the feet's normal
forces as weights, so that the estimate stays continuous when the load passes from one foot to the other). The ZMP
stays measured in the world.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..robots import Robot
from ..side import Side
from ..types import Measurement
from .wrench import FootMass, contact_wrench_from_ft
from .zmp import DEFAULT_MIN_NORMAL_FORCE, zmp_from_wrenches


class BalanceEstimator:
    """Measured ZMP and support-foot-anchored CoM of a robot, one `update` per control tick.

    Args:
        robot: the robot (its profile gives the sole and F/T sensor frames; the foot masses below the sensors
            come from the model).
        dt: control period [s] (CoM velocity by finite difference).
        velocity_cutoff_hz: first-order low-pass on that finite difference; None: unfiltered.
        min_normal_force: per-foot normal-force threshold for the ZMP [N].
    """

    def __init__(self, robot: Robot, dt: float, velocity_cutoff_hz: float | None = 50.0,
                 min_normal_force: float = DEFAULT_MIN_NORMAL_FORCE):
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.model_data = robot.model.createData()
        self.dt = dt
        self.min_normal_force = min_normal_force
        self.sensor_ids = {s: robot.model.getFrameId(robot.profile.feet[s].ft_sensor_frame) for s in Side}
        self.sole_ids = {s: robot.sole_frame_id(s) for s in Side}
        self.feet = {}
        for s in Side:
            m, c = robot.foot_below_sensor(s)
            self.feet[s] = FootMass(m, c)
        self.alpha = 1.0 if velocity_cutoff_hz is None else 1 - np.exp(-2 * np.pi * velocity_cutoff_hz * dt)
        self.reset()

    def reset(self) -> None:
        self._com_prev = None
        self.com_vel = np.zeros(3)
        self.com = np.zeros(3)
        self.zmp = np.full(3, np.nan)
        self.normal_force = {s: 0.0 for s in Side}
        self.support = Side.LEFT

    def update(self, meas: Measurement, q_model: np.ndarray | None = None) -> None:
        """Update ZMP (world) and CoM from one measurement; `q_model` is the controller's model
        configuration whose support foot anchors the CoM (default: the measurement itself)."""
        m, d = self.model, self.data
        pin.forwardKinematics(m, d, meas.q)
        wrenches = []
        for s in Side:
            M = pin.updateFramePlacement(m, d, self.sensor_ids[s])
            w = contact_wrench_from_ft(meas.ft_force[s], meas.ft_torque[s], M.rotation, M.translation, self.feet[s])
            wrenches.append(w)
            self.normal_force[s] = float(w.force[2])
        self.support = max(Side, key=lambda s: self.normal_force[s])
        ground = pin.updateFramePlacement(m, d, self.sole_ids[self.support]).translation[2]
        self.zmp = zmp_from_wrenches(wrenches, ground, min_normal_force=self.min_normal_force)
        # anchored CoM: joints as measured, each loaded foot where the model has it, blended by normal force
        com_world = pin.centerOfMass(m, d, meas.q, False)
        if q_model is not None:
            com_world = self._anchored(com_world, q_model)
        self.com = com_world.copy()
        if self._com_prev is None:
            self.com_vel = np.zeros(3)
        else:
            raw = (self.com - self._com_prev) / self.dt
            self.com_vel = self.com_vel + self.alpha * (raw - self.com_vel)
        self._com_prev = self.com.copy()

    def _anchored(self, com_world: np.ndarray, q_model: np.ndarray) -> np.ndarray:
        """`com_world` (from the measured configuration) moved so that the loaded feet sit where the model has
        them: one rigid correction per foot, averaged with the feet's normal forces as weights. A single-foot
        anchor would jump whenever the load passes from one foot to the other and the two feet's errors differ
        (feet on two opposite slopes, a foot that slid): at 0.9 m above the sole a 0.05 rad difference is a
        4.5 cm CoM step, i.e. a velocity spike of tens of m/s in the DCM."""
        m, d, md = self.model, self.data, self.model_data
        pin.forwardKinematics(m, md, q_model)
        forces = {s: (f if f > self.min_normal_force else 0.0) for s, f in self.normal_force.items()}
        total = forces[Side.LEFT] + forces[Side.RIGHT]
        if total <= 0.0:
            forces, total = {self.support: 1.0}, 1.0
        out = np.zeros(3)
        for s, f in forces.items():
            if f <= 0.0:
                continue
            fid = self.sole_ids[s]
            T_meas = pin.updateFramePlacement(m, d, fid)
            T_model = pin.updateFramePlacement(m, md, fid)
            out += (f / total) * (T_model * T_meas.inverse()).act(com_world)
        return out
