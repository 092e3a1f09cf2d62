"""The balance stabilizer in front of a position-controlled whole-body controller (paper 000 Section 3.1,
Eq. 2-4): the ZMP measured by the ankle F/T sensors and the support-anchored CoM (`BalanceEstimator`) feed the
DCM PI + CoM admittance (`DcmStabilizer`), which corrects the CoM reference the controller tracks."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..config import Section
from ..estimation import BalanceEstimator
from ..robots import Robot
from ..side import Side
from ..types import Measurement, ModelFeedback, PointReference, References
from .base import Stabilizer
from ..estimation.balance import balance_step
from ..jit import njit
from .dcm import DcmGains, DcmStabilizer, _dcm_step_logged

_F64 = np.dtype(np.float64)
_LEFT, _RIGHT = Side.LEFT, Side.RIGHT


class BalanceStabilizer(Stabilizer):
    """Corrects each tick's CoM reference from the measured ZMP and anchored CoM (task-set `type: dcm`).

    Needs the scenario's CoM and ZMP plans. `log` holds (measured ZMP x y, desired ZMP x y, measured DCM x y)
    of the last tick [m]. The anchored CoM uses the controller's model configuration (`ModelFeedback.q`).
    """

    type = "dcm"
    requires = ("com", "zmp")
    LOG_LABELS = ("zmp_x", "zmp_y", "zmp_des_x", "zmp_des_y", "dcm_x", "dcm_y")

    @classmethod
    def parse(cls, sec: Section) -> DcmGains:
        cutoff = sec.raw("zmp_cutoff_hz", None)
        gains = DcmGains(kp_adm=sec.float("kp_adm", min=0.0), kp_dcm=sec.float("kp_dcm", min=0.0),
                         ki_dcm=sec.float("ki_dcm", min=0.0), kz_dcm=sec.float("kz_dcm", min=0.0),
                         integral_limit=sec.float("integral_limit", 0.1, positive=True),
                         zmp_cutoff_hz=None if cutoff is None else sec.float("zmp_cutoff_hz", positive=True))
        sec.finish()
        return gains

    def __init__(self, robot: Robot, gains: DcmGains, dt: float):
        self.robot = robot
        self.gains = gains
        self.dt = dt
        # the estimator's state (7) and the log (6) in one array: one argument of `_estimate_and_step`
        self._arrays = np.zeros(13)
        self.estimator = BalanceEstimator(robot, dt, state=self._arrays[:7])
        self.dcm: DcmStabilizer | None = None
        self.log = self._arrays[7:]
        self.log[:] = np.nan

    def reset(self, meas: Measurement, refs: References, feedback: ModelFeedback) -> None:
        """Restart from the model's configuration standing on the ground (sets the nominal CoM height)."""
        q_model = feedback.q
        m = self.robot.model
        d = m.createData()
        pin.framesForwardKinematics(m, d, q_model)
        ground = min(d.oMf[self.robot.sole_frame_id(s)].translation[2] for s in Side)
        com = pin.centerOfMass(m, d, q_model)
        self.estimator.reset()
        self.dcm = DcmStabilizer(self.gains, dt=self.dt, com_height=float(com[2] - ground))
        self.log[:] = np.nan

    def correct(self, meas: Measurement, refs: References, feedback: ModelFeedback) -> References:
        """The references with the CoM corrected; unchanged while no foot is loaded (no measured ZMP), or on a
        tick without a CoM/ZMP plan."""
        com = refs.com
        zmp = refs.zmp
        if zmp is None or com is None:
            return refs
        est = self.estimator
        if (est._step_args is not None and type(zmp) is np.ndarray and zmp.dtype == _F64 and zmp.ndim == 1
                and 2 <= zmp.shape[0] <= 3):
            # the estimator's update and the DCM step in one compiled call (the same kernels, the same numbers),
            # their outputs in one new array: the estimate's (11), the DCM step's (20)
            dcm = self.dcm
            out = np.empty(31)
            force, torque = meas.ft_force, meas.ft_torque
            m_ints, m_floats, parents, floats = est._step_args  # a call without *: no tuple built
            code = _estimate_and_step(meas.q, feedback.q, force[_LEFT], torque[_LEFT], force[_RIGHT], torque[_RIGHT],
                                      m_ints, m_floats, parents, floats, self._arrays, com.position, com.velocity,
                                      com.acceleration, zmp, dcm._arrays, dcm._fresh, out)
            est._take(out, code & 1)
            if code < 2:  # no loaded foot: no measured ZMP
                return refs
            if code >= 4:  # an input not finite: the numpy law raises, naming it
                dcm._step_numpy(com.position, com.velocity, com.acceleration, zmp, est.com, est.com_vel, est.zmp)
            if dcm._filter is not None:
                dcm._fresh = False
            return refs.corrected(PointReference.unchecked(out[11:14], out[14:17], out[17:20]), refs.targets,
                                  refs.wrench_targets, refs.contact_poses)
        est.update(meas, feedback.q)
        p_zmp = est.zmp
        z0, z1, z2 = p_zmp.tolist()
        if not (math.isfinite(z0) and math.isfinite(z1) and math.isfinite(z2)):
            return refs
        if type(zmp) is np.ndarray and zmp.dtype == _F64 and zmp.ndim == 1 and 2 <= zmp.shape[0] <= 3:
            # the CoM reference's and the estimator's arrays are float64 (3,): the stabilizer's arithmetic in one
            # compiled call that also writes the log (the same numbers as `DcmStabilizer.step`)
            out = self.dcm.step_array(com.position, com.velocity, com.acceleration, zmp, est.com, est.com_vel,
                                      p_zmp, self.log)
            p, v, a = out[0:3], out[3:6], out[6:9]
        else:
            res = self.dcm.step(p_com_ref=com.position, v_com_ref=com.velocity, a_com_ref=com.acceleration,
                                p_zmp_ref=zmp, p_com=est.com, v_com=est.com_vel, p_zmp=p_zmp)
            self.log[:2] = res.p_world_zmp_measured
            self.log[2:4] = res.p_world_zmp_desired
            self.log[4:6] = res.p_world_dcm
            p, v, a = res.p_world_com, res.v_world_com, res.a_world_com
        # the stabilizer's outputs are new float64 (3,) arrays, finite (its inputs were checked): no copies
        return refs.corrected(PointReference.unchecked(p, v, a), refs.targets, refs.wrench_targets,
                              refs.contact_poses)


@njit(exact=True)
def _estimate_and_step(q_meas, q_model, f_left, m_left, f_right, m_right, memo_ints, memo_floats, frame_parents,
                       floats, arrays, c_ref, v_ref, a_ref, z_ref, dcm_arrays, fresh, out):
    """`BalanceEstimator.update` anchored on ``q_model`` (`_balance_step`, into ``out[:11]``) and, when it
    measured a ZMP, the DCM step on its estimate (`_dcm_step_logged`, into ``out[11:31]`` and ``log``): a tick of
    `correct` in one call. ``arrays``: the stabilizer's (the estimator's state, the log), ``dcm_arrays``: the DCM
    stabilizer's (its constants, its state). Returns the support foot (0 left, 1 right) + 2 when the DCM step
    ran, + 4 when it refused a non-finite input. `exact` as the DCM step, which it inlines (its own code only
    compares)."""
    est_state, log = arrays[0:7], arrays[7:13]
    k, dcm_state = dcm_arrays[0:13], dcm_arrays[13:21]
    est_out, dcm_out = out[0:11], out[11:31]
    support = balance_step(q_meas, q_model, True, f_left, m_left, f_right, m_right, memo_ints, memo_floats,
                            frame_parents, floats, est_state, est_out)
    if not (np.isfinite(est_out[2]) and np.isfinite(est_out[3]) and np.isfinite(est_out[4])):
        return support
    if not _dcm_step_logged(c_ref, v_ref, a_ref, z_ref, est_out[5:8], est_out[8:11], est_out[2:5], k, fresh,
                            dcm_state, dcm_out, log):
        return support + 6
    return support + 2
