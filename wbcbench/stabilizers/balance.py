"""The balance stabilizer in front of a position-controlled whole-body controller (paper 000 Section 3.1,
Eq. 2-4): the ZMP measured by the ankle F/T sensors and the support-anchored CoM (`BalanceEstimator`) feed the
DCM PI + CoM admittance (`DcmStabilizer`), which corrects the CoM reference the controller tracks."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin

from ..estimation import BalanceEstimator
from ..robots import Robot
from ..side import Side
from ..types import Measurement, References
from .dcm import DcmGains, DcmStabilizer


class BalanceStabilizer:
    """Corrects each tick's CoM reference from the measured ZMP and anchored CoM.

    `log_values()` gives (measured ZMP x y, desired ZMP x y, measured DCM x y) of the last tick [m].
    """

    LOG_LABELS = ["zmp_x", "zmp_y", "zmp_des_x", "zmp_des_y", "dcm_x", "dcm_y"]

    def __init__(self, robot: Robot, gains: DcmGains, dt: float):
        self.robot = robot
        self.gains = gains
        self.dt = dt
        self.estimator = BalanceEstimator(robot, dt)
        self.dcm: DcmStabilizer | None = None
        self.log = np.full(6, np.nan)

    def reset(self, q_model: np.ndarray) -> None:
        """Restart from a configuration standing on the ground (sets the nominal CoM height)."""
        m = self.robot.model
        d = m.createData()
        pin.framesForwardKinematics(m, d, q_model)
        ground = min(d.oMf[self.robot.sole_frame_id(s)].translation[2] for s in Side)
        com = pin.centerOfMass(m, d, q_model)
        self.estimator.reset()
        self.dcm = DcmStabilizer(self.gains, dt=self.dt, com_height=float(com[2] - ground))
        self.log[:] = np.nan

    def correct(self, meas: Measurement, refs: References, q_model: np.ndarray) -> References:
        """The references with the CoM corrected; unchanged when the scenario gives no ZMP/CoM plan or no foot
        is loaded."""
        if refs.zmp is None or refs.com is None:
            return refs
        est = self.estimator
        est.update(meas, q_model)
        if not np.all(np.isfinite(est.zmp)):
            return refs
        out = self.dcm.step(p_com_ref=refs.com, v_com_ref=refs.com_vel, a_com_ref=refs.com_acc, p_zmp_ref=refs.zmp,
                            p_com=est.com, v_com=est.com_vel, p_zmp=est.zmp)
        self.log[:2] = out.p_world_zmp_measured
        self.log[2:4] = out.p_world_zmp_desired
        self.log[4:6] = out.p_world_dcm
        return replace(refs, com=out.p_world_com, com_vel=out.v_world_com, com_acc=out.a_world_com)
