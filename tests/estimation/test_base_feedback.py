"""Base feedback: the drift of the integrated model from the measured robot, from the feet in contact."""

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.estimation.base_feedback import BaseFeedback, BaseFeedbackConfig
from wbcbench.side import Side
from wbcbench.types import Measurement, PointReference, PoseReference, References


def _shifted(q, dx, dy, dyaw):
    """q with its base moved by the planar transform (dx, dy, dyaw) applied in the world."""
    q = q.copy()
    R = pin.Quaternion(q[6], *q[3:6]).toRotationMatrix()
    Rz = pin.rpy.rpyToMatrix(0.0, 0.0, dyaw)
    q[:3] = Rz @ q[:3] + np.array([dx, dy, 0.0])
    quat = pin.Quaternion(Rz @ R)
    q[3:7] = [quat.x, quat.y, quat.z, quat.w]
    return q


def _meas(q):
    return Measurement(t=0.0, q=q, v=np.zeros(q.size - 1), imu_quat=np.array([0, 0, 0, 1.0]), gyro=np.zeros(3),
                       accelerometer=np.zeros(3))


def test_drift_is_the_transform_from_the_robot_to_the_model_and_references_follow(talos):
    q_model = talos.q0.copy()
    q_real = _shifted(q_model, 0.03, -0.05, np.radians(-5.0))    # the real robot: 5 deg and 6 cm off the model
    fb = BaseFeedback(talos, 1e-3, BaseFeedbackConfig(time_constant=0.01))
    refs = References(t=0.0, contacts=frozenset(Side), com=PointReference([1.0, 0.0, 0.87], [0.1, 0.0, 0.0]),
                      zmp=np.array([1.0, 0.0, 0.0]))
    for _ in range(200):
        out = fb.correct(_meas(q_real), refs, q_model)
    # D undoes the real robot's offset: a point of the real robot maps onto the same point of the model
    R, p = fb.transform()
    x_real = _shifted(np.r_[np.array([0.4, 0.2, 0.1]), 0, 0, 0, 1.0], 0.03, -0.05, np.radians(-5.0))[:3]
    assert R @ x_real + p == pytest.approx([0.4, 0.2, 0.1], abs=1e-6)
    assert np.degrees(fb.drift[2]) == pytest.approx(5.0, abs=1e-6)
    assert out.com.position == pytest.approx(R @ refs.com.position + p)
    assert out.com.velocity == pytest.approx(R @ refs.com.velocity)
    assert out.zmp is refs.zmp                                   # the ZMP stays in the world


def test_no_drift_when_the_model_is_the_robot_and_held_in_single_support(talos):
    fb = BaseFeedback(talos, 1e-3)
    fb.update(_meas(talos.q0), talos.q0, frozenset(Side))
    assert np.abs(fb.drift).max() < 1e-12
    for contacts in (frozenset(), frozenset({Side.LEFT})):
        fb.update(_meas(_shifted(talos.q0, 0.1, 0, 0)), talos.q0, contacts)
        assert np.abs(fb.drift).max() < 1e-12


def test_a_lifted_foot_starts_where_the_model_foot_stands_and_blends_to_the_mapped_plan(talos):
    """The drift changes while a foot stands (double support); at its lift-off the swing reference must start at
    the model's foot, not at the plan mapped by the new drift (a jump of the swing task), and reach the mapped plan
    after the blend."""
    q_model = talos.q0.copy()
    q_real = _shifted(q_model, 0.02, -0.04, np.radians(-3.0))
    fb = BaseFeedback(talos, 1e-3, BaseFeedbackConfig(time_constant=0.01, liftoff_blend=0.2))
    d = talos.model.createData()
    pin.framesForwardKinematics(talos.model, d, q_model)
    M_left = d.oMf[talos.sole_frame_id(Side.LEFT)].copy()
    both = References(t=0.0, contacts=frozenset(Side), com=PointReference([0.0, 0.0, 0.87]), zmp=np.zeros(3))
    for _ in range(200):                                   # double support: D converges to the offset
        fb.correct(_meas(q_real), both, q_model)
    R, p = fb.transform()
    assert np.abs(fb.drift).max() > 0.01
    swing_ref = PoseReference(M_left.translation.copy(), M_left.rotation.copy())   # the plan: the foot at rest
    out = None
    for k in range(301):                                   # single support on the right foot, the left swinging
        refs = References(t=0.2 + k * 1e-3, contacts=frozenset({Side.RIGHT}), com=both.com, zmp=both.zmp,
                          feet={Side.LEFT: swing_ref})
        out = fb.correct(_meas(q_real), refs, q_model)
        if k == 0:   # lift-off: the reference is the model's foot
            assert out.feet[Side.LEFT].position == pytest.approx(M_left.translation, abs=1e-9)
            assert out.feet[Side.LEFT].rotation == pytest.approx(M_left.rotation, abs=1e-9)
        if k == 100:  # half way: between the two, moving towards the mapped plan
            v = out.feet[Side.LEFT].velocity[:3]
            target = R @ M_left.translation + p
            assert np.dot(v, target - M_left.translation) > 0.0
    # after the blend: the plan mapped by D
    assert out.feet[Side.LEFT].position == pytest.approx(R @ M_left.translation + p, abs=1e-9)
    assert out.feet[Side.LEFT].rotation == pytest.approx(R @ M_left.rotation, abs=1e-9)
    assert np.abs(out.feet[Side.LEFT].velocity).max() < 1e-12


def test_the_compiled_drift_step_is_pinocchios_to_rounding(talos):
    """`update` in one compiled call (the compiled forward kinematics) against the same update through
    pinocchio's frames, on random configurations of the model and the robot, step after step."""
    rng = np.random.default_rng(2)
    fast = BaseFeedback(talos, 1e-3, BaseFeedbackConfig(time_constant=0.05))
    slow = BaseFeedback(talos, 1e-3, BaseFeedbackConfig(time_constant=0.05))
    assert fast._fk.supported
    slow._fk.supported = False
    lo, hi = talos.position_limits
    for k in range(50):
        q_model, q_real = talos.q0.copy(), talos.q0.copy()
        q_model[7:] = rng.uniform(lo, hi)
        q_real[7:] = np.clip(q_model[7:] + 0.05 * rng.normal(size=talos.na), lo, hi)
        q_real = _shifted(q_real, *rng.normal(scale=[0.05, 0.05, 0.2]))
        a = fast.update(_meas(q_real), q_model, frozenset(Side))
        b = slow.update(_meas(q_real), q_model, frozenset(Side))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    assert np.abs(fast.drift).max() > 1e-3  # the states moved it


def test_double_support_tick_in_one_call_gives_the_numbers_of_update_then_mapping(talos):
    """`correct` in double support (the drift update, its transform and the CoM's mapping in one compiled call)
    against `update`, `transform` and the mapping of a single reference, bit for bit."""
    from wbcbench.estimation.base_feedback import _map_point

    q_model = talos.q0.copy()
    q_real = _shifted(q_model, 0.01, 0.02, np.radians(2.0))
    fused, steps = (BaseFeedback(talos, 1e-3, BaseFeedbackConfig(time_constant=0.05)) for _ in range(2))
    refs = References(t=0.0, contacts=frozenset(Side), com=PointReference([0.1, 0.02, 0.87], [0.1, -0.2, 0.0],
                                                                          [0.5, 0.3, -0.1]),
                      zmp=np.array([0.1, 0.0, 0.0]))
    for k in range(20):
        q_meas = _shifted(q_real, 1e-4 * k, 0.0, 0.0)
        out = fused.correct(_meas(q_meas), refs, q_model)
        steps.update(_meas(q_meas), q_model, refs.contacts)
        R, p = steps.transform()
        expected = np.empty(9)
        _map_point(R, p, refs.com.position, refs.com.velocity, refs.com.acceleration, expected)
        assert np.array_equal(fused.drift, steps.drift)
        assert np.array_equal(np.r_[out.com.position, out.com.velocity, out.com.acceleration], expected)
        assert all(np.array_equal(a, b) for a, b in zip(fused.transform(), (R, p)))


@pytest.mark.parametrize("with_rotation", [True, False])
def test_the_compiled_liftoff_offset_is_the_numpy_arithmetic_bit_for_bit(with_rotation):
    """`_from_liftoff`'s offset in one compiled call (`_liftoff_offset`) against the numpy expressions it replaced."""
    from wbcbench.estimation.base_feedback import _NO_POINT, _liftoff_offset

    rng = np.random.default_rng(5)
    for _ in range(50):
        p, v, a, dp, dphi = rng.normal(size=3), rng.normal(size=6), rng.normal(size=6), rng.normal(size=3), \
            rng.normal(size=3)
        b, db, ddb = rng.uniform(0.0, 1.0), rng.normal(), rng.normal()
        out = np.empty(15)
        _liftoff_offset(p, v, a, dp, dphi if with_rotation else _NO_POINT, b, db, ddb, out)
        vel, acc = v.copy(), a.copy()
        vel[:3] -= db * dp
        acc[:3] -= ddb * dp
        if with_rotation:
            vel[3:] -= db * dphi
            acc[3:] -= ddb * dphi
        assert np.array_equal(out, np.r_[p + (1.0 - b) * dp, vel, acc])
