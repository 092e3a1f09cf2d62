"""BalanceEstimator: the support-anchored CoM stays continuous when the load passes from one foot to the other,
even when the two feet disagree with the model (a foot that slid, feet on two opposite slopes)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.estimation import BalanceEstimator
from wbcbench.robots import load_robot
from wbcbench.side import Side
from wbcbench.types import Measurement


@pytest.fixture(scope="module")
def talos():
    return load_robot("talos")


def _measurement(robot, q, load_left):
    """Standing still in q, `load_left` of the weight on the left foot, the CoP under each ankle."""
    m, d = robot.model, robot.model.createData()
    pin.framesForwardKinematics(m, d, q)
    mg = robot.mass * 9.81
    ft_f, ft_t = {}, {}
    for s in Side:
        est_foot_mass, _ = robot.foot_below_sensor(s)
        R = d.oMf[m.getFrameId(robot.profile.feet[s].ft_sensor_frame)].rotation
        share = load_left if s is Side.LEFT else 1.0 - load_left
        F = np.array([0.0, 0.0, share * mg])
        ft_f[s] = -R.T @ (F + est_foot_mass * np.array([0.0, 0.0, -9.81]))
        ft_t[s] = np.zeros(3)
    return Measurement(t=0.0, q=q, v=np.zeros(robot.nv), imu_quat=q[3:7], gyro=np.zeros(3),
                       accelerometer=np.array([0.0, 0.0, 9.81]), ft_force=ft_f, ft_torque=ft_t)


def test_anchored_com_is_continuous_when_the_load_changes_feet(talos):
    q_meas = talos.q0.copy()
    q_model = talos.q0.copy()
    # the model's left ankle pitch differs from the measurement by 0.05 rad: its left foot is tilted
    jl = talos.model.joints[talos.model.getJointId("leg_left_5_joint")].idx_q
    q_model[jl] += 0.05
    est = BalanceEstimator(talos, dt=1e-3, velocity_cutoff_hz=None)
    coms = []
    for share in np.linspace(0.0, 1.0, 101):
        est.update(_measurement(talos, q_meas, share), q_model)
        coms.append(est.com.copy())
    coms = np.array(coms)
    ends = np.linalg.norm(coms[-1] - coms[0])
    assert ends > 0.02      # anchored on the left foot vs on the right foot: centimetres apart
    steps = np.linalg.norm(np.diff(coms, axis=0), axis=1)
    # a single-foot anchor jumps by `ends` at 50 %; the force-weighted one moves about ends / 100 per 1 %
    assert steps.max() < 3.0 * ends / 100
    # all on one foot: that foot's anchor (the measured CoM moved so that foot sits where the model has it)
    m, d, dm = talos.model, talos.model.createData(), talos.model.createData()
    pin.framesForwardKinematics(m, d, q_meas)
    pin.framesForwardKinematics(m, dm, q_model)
    c = pin.centerOfMass(m, d, q_meas)
    for com, s in ((coms[0], Side.RIGHT), (coms[-1], Side.LEFT)):
        fid = talos.sole_frame_id(s)
        np.testing.assert_allclose(com, (dm.oMf[fid] * d.oMf[fid].inverse()).act(c), atol=1e-9)


def test_compiled_update_matches_pinocchio(talos):
    """The compiled update (the default for free-flyer / revolute robots) gives the pinocchio path's ZMP,
    anchored CoM, CoM velocity and support foot to rounding, on random states with one foot unloaded at times
    and with and without a model configuration to anchor on."""
    rng = np.random.default_rng(0)
    fast, slow = BalanceEstimator(talos, 1e-3), BalanceEstimator(talos, 1e-3)
    assert fast._step_args is not None
    slow._step_args = None  # the pinocchio path
    for k in range(200):
        q = talos.q0 + 0.05 * rng.standard_normal(talos.nq)
        q[3:7] /= np.linalg.norm(q[3:7])
        q_model = q + 0.01 * rng.standard_normal(talos.nq)
        q_model[3:7] /= np.linalg.norm(q_model[3:7])
        force = {s: rng.standard_normal(3) * 300.0 for s in Side}
        torque = {s: rng.standard_normal(3) * 20.0 for s in Side}
        if k % 7 == 0:
            force[Side.LEFT] = np.zeros(3)
        meas = Measurement(0.0, q, np.zeros(talos.nv), q[3:7], np.zeros(3), np.zeros(3), force, torque)
        anchor = q_model if k % 5 else None
        fast.update(meas, anchor)
        slow.update(meas, anchor)
        assert fast.support == slow.support
        for s in Side:
            assert fast.normal_force[s] == pytest.approx(slow.normal_force[s], rel=1e-12, abs=1e-9)
        np.testing.assert_array_equal(np.isnan(fast.zmp), np.isnan(slow.zmp))
        np.testing.assert_allclose(fast.zmp, slow.zmp, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(fast.com, slow.com, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(fast.com_vel, slow.com_vel, rtol=1e-9, atol=1e-9)
