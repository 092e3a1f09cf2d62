"""Swing-foot tilt compensation: a swing foot turned against the tilt the stance leg's yielding joints give it."""

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.controllers.swing_tilt import SwingTilt, SwingTiltConfig
from wbcbench.controllers.taskset import load_taskset, taskset_path
from wbcbench.errors import ConfigError
from wbcbench.planning.geometry import so3_log
from wbcbench.side import Side
from wbcbench.types import Measurement, PoseReference, References

L, R = Side.LEFT, Side.RIGHT
PLAN_R = np.eye(3)


def _meas(q):
    return Measurement(t=0.0, q=q, v=np.zeros(len(q) - 1), imu_quat=np.array([0, 0, 0, 1.0]), gyro=np.zeros(3),
                       accelerometer=np.zeros(3))


def _swing(t):
    return References(t=t, contacts=frozenset({R}), feet={L: PoseReference([0.1, 0.1, 0.03], PLAN_R)})


def _joint_q(robot, name):
    return robot.model.joints[robot.model.getJointId(name)].idx_q


def _turn(tilt, q_meas, q_model, ticks=400):
    """The left swing foot's reference rotation (as a rotation vector) after `ticks` single-support ticks."""
    out = None
    for k in range(ticks):
        out = tilt.correct(_meas(q_meas), _swing(k * 0.001), q_model)
    return so3_log(out.feet[L].rotation)


def test_the_stance_legs_deflection_turns_the_swing_foot_against_it(talos):
    tilt = SwingTilt(SwingTiltConfig(gain=0.3, max_tilt=0.05, time_constant=0.05, settle=0.1), talos, 0.001)
    q_model = talos.q0.copy()
    # the stance (right) hip roll yields by 0.02 rad: the swing sole turns by about 0.02 rad about its x axis
    q_meas = q_model.copy()
    q_meas[_joint_q(talos, "leg_right_2_joint")] += 0.02
    w = _turn(tilt, q_meas, q_model)
    assert abs(w[0]) == pytest.approx(0.3 * 0.02, rel=0.05)
    assert abs(w[1]) < 1e-3 and w[2] == pytest.approx(0.0, abs=1e-9)
    # the opposite deflection, the opposite turn
    tilt.reset()
    q_meas[_joint_q(talos, "leg_right_2_joint")] -= 0.04
    assert _turn(tilt, q_meas, q_model)[0] == pytest.approx(-w[0], rel=0.05)
    # the swing leg's own tracking error is left out; an undeflected stance leg leaves the plan's orientation
    tilt.reset()
    q_meas = q_model.copy()
    q_meas[_joint_q(talos, "leg_left_2_joint")] += 0.02
    assert np.abs(_turn(tilt, q_meas, q_model)).max() < 1e-9


def test_the_turn_is_bounded_and_the_contact_turns_back_to_the_plan(talos):
    tilt = SwingTilt(SwingTiltConfig(gain=1.0, max_tilt=0.01, time_constant=0.05, settle=0.1), talos, 0.001)
    q_model = talos.q0.copy()
    q_meas = q_model.copy()
    q_meas[_joint_q(talos, "leg_right_3_joint")] += 0.03   # stance hip pitch
    w = _turn(tilt, q_meas, q_model)
    assert np.linalg.norm(w) == pytest.approx(0.01)
    assert tilt.max_tilt == pytest.approx(0.03, rel=0.05)
    turned = tilt._ref[L].rotation
    # touch-down: the model's contact is turned back to the plan's orientation over 0.1 s (a quintic)
    landed = [tilt.correct(_meas(q_meas), References(t=0.4 + k * 0.001, contacts=frozenset(Side)), q_model)
              for k in range(120)]
    angle = [float(np.linalg.norm(so3_log(PLAN_R.T @ r.contact_poses[L].rotation))) if L in r.contact_poses
             else None for r in landed]
    np.testing.assert_allclose(landed[0].contact_poses[L].rotation, turned)
    assert angle[50] == pytest.approx(0.005, rel=0.02)                 # halfway
    assert angle[100] == pytest.approx(0.0, abs=1e-9) and angle[110] is None     # then left to the contact
    np.testing.assert_allclose(landed[0].contact_poses[L].position, [0.1, 0.1, 0.03])


def test_taskset_key_and_its_errors(talos, tmp_path):
    spec = load_taskset(taskset_path(talos, "tsid-position-platforms"), talos)
    assert spec.swing_tilt == SwingTiltConfig(gain=0.3, max_tilt=0.05, time_constant=0.05, settle=0.1)
    assert load_taskset(taskset_path(talos, "tsid-position"), talos).swing_tilt is None
    assert load_taskset(taskset_path(talos, "tsid-position-stairs"), talos).swing_tilt is None
    text = taskset_path(talos, "tsid-position-platforms").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("swing_tilt: {gain: 0.3,", "swing_tilt: {gain: -0.3,"))
    with pytest.raises(ConfigError, match="gain") as err:
        load_taskset(bad, talos)
    assert "bad.yaml" in str(err.value) and "\n" not in str(err.value)
    bad.write_text(text.replace("swing_tilt: {gain: 0.3,", "swing_tilt: {gian: 0.3,"))
    with pytest.raises(ConfigError, match="gian"):
        load_taskset(bad, talos)


def test_tsid_position_lands_flatter_on_the_platforms(talos, tmp_path):
    """TALOS' TSID position platforms set: the stance leg's measured tilt turns the swing feet (up to about 0.02
    rad measured); the robot crosses, with the ZMP x mean lower than without (0.0152 m)."""
    from wbcbench.runner import run

    res = run("platforms-quick", "tsid-position", talos, out=tmp_path)
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    assert 0.005 < s["controller_status"]["swing_tilt_max_rad"] < 0.05
    # x / y mean 0.0139 / 0.0105 m; without the compensation 0.0152 / 0.0117
    assert s["metrics"]["zmp_error_m"]["x"]["mean"] < 0.0145
    assert s["metrics"]["zmp_error_m"]["y"]["mean"] < 0.0117
