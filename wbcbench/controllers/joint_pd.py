"""Joint-space PD around the reference posture.

Torque mode: tau = Kp (q_ref - q) - Kd v + tau_comp, where tau_comp compensates gravity and the contact
forces that carry the robot: with g(q) the generalized gravity and J_c the stacked sole Jacobians (LOCAL), the
contact wrenches f solve the base rows g_base = J_c,base^T f in the least-norm sense and
tau_comp = g_act - J_c,act^T f. Position and SPD modes: the reference posture goes to the joint servos.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..robots import Robot, Side
from ..types import ActuationMode
from ..types import Command, Measurement, References
from .base import Controller


class JointPD(Controller):
    name = "joint-pd"
    modes = (ActuationMode.TORQUE, ActuationMode.POSITION, ActuationMode.SPD)

    def __init__(self, robot: Robot, mode: ActuationMode, dt: float):
        super().__init__(robot, mode, dt)
        self.kp, self.kd = robot.profile.torque_pd_gains.resolve(robot.joint_names, robot.profile.file)
        self.q_ref = robot.q0[7:].copy()
        self.model = robot.model
        self.data = robot.model.createData()
        self._zero_v = np.zeros(robot.nv)
        self._sole_ids = {s: robot.sole_frame_id(s) for s in Side}
        self._tau = np.zeros(robot.na)

    def reset(self, meas: Measurement, refs: References) -> None:
        pass

    def compensation(self, q: np.ndarray, contacts) -> np.ndarray:
        """Joint torques (na,) that hold the robot still under gravity with the given feet carrying it."""
        m, d = self.model, self.data
        g = pin.computeGeneralizedGravity(m, d, q)
        if not contacts:
            return g[6:].copy()
        pin.computeJointJacobians(m, d, q)
        J = np.vstack([pin.getFrameJacobian(m, d, self._sole_ids[s], pin.LOCAL) for s in sorted(contacts)])
        f = np.linalg.lstsq(J[:, :6].T, g[:6], rcond=None)[0]
        return g[6:] - J[:, 6:].T @ f

    def step(self, meas: Measurement, refs: References) -> Command:
        if self.mode is ActuationMode.TORQUE:
            q, v = meas.q, meas.v
            self._tau = self.kp * (self.q_ref - q[7:]) - self.kd * v[6:] + self.compensation(q, refs.contacts)
            return Command(tau=self._tau)
        return Command(q=self.q_ref, v=np.zeros(self.robot.na))
