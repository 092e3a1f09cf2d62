"""tsid-teleop in SPD mode: each arm joint's acceleration bounded by a share of its torque limit, so that the
integrated arm moves only as fast as the arm's actuators can follow it (wbcbench/controllers/teleop.py)."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.controllers.teleop import TSIDTeleop, arm_acceleration_bounds, arm_joints, inject_damping
from wbcbench.errors import ConfigError
from wbcbench.runner import run
from wbcbench.scenarios.teleop_kind import TeleopScenario
from wbcbench.types import ActuationMode


def test_arm_joints_are_the_fourteen_arm_joints(talos):
    m = talos.model
    names = [m.names[j] for j in range(1, m.njoints) if m.joints[j].idx_v in set(arm_joints(talos).tolist())]
    assert names == [f"arm_{s}_{k}_joint" for s in ("left", "right") for k in range(1, 8)]


def test_arm_acceleration_bounds_intersect_the_joint_limit_bounds():
    M = np.diag([1.0] * 6 + [2.0, 4.0, 1.0])
    nle = np.array([0.0] * 6 + [1.0, 0.0, 0.0])
    idx = np.array([6, 7, 8])
    tau_max = np.array([10.0, 10.0, 10.0])
    lb, ub = np.array([-100.0, -1.0, 20.0]), np.array([100.0, 1.0, 30.0])
    saved = np.zeros((2, 3))
    arm_acceleration_bounds(M, nle, idx, tau_max, 0.5, lb, ub, saved)
    # joint 0: (+-5 - 1) / 2; joint 1: the joint-limit bounds are inside (+-5 / 4); joint 2: [-5, 5] misses
    # [20, 30]: the joint-limit bounds are kept
    assert np.allclose(lb, [-3.0, -1.0, 20.0]) and np.allclose(ub, [2.0, 1.0, 30.0])
    assert np.allclose(saved, [[-100.0, -1.0, 20.0], [100.0, 1.0, 30.0]])


def test_the_measured_arm_follows_the_integrated_arm_on_a_fast_motion(talos, tmp_path):
    """The joint servos get positions and velocities only and saturate at the arms' torque limits (URDF
    efforts). The shipped bimanual push-pull replayed twice as fast asks the arms for more: with the integrated
    arm unbounded the measured arm lags it by 0.26 rad (the lag, up to 0.9 rad, that let the real gripper hit the
    thigh on public motion-capture recordings while the model's stayed outside the repulsors); with each arm
    joint's acceleration bounded by 0.7 of its torque limit, by 0.12 rad (both without the damping injection)."""
    idx = arm_joints(talos)

    class Probe(TSIDTeleop):
        lag = 0.0

        def step(self, meas, refs):
            cmd = super().step(meas, refs)
            self.lag = max(self.lag, float(np.abs(self.q_int[idx + 1] - meas.q[idx + 1]).max()))
            return cmd

    from dataclasses import replace

    from wbcbench.controllers.teleop import teleop_taskset

    spec = replace(teleop_taskset(talos), arm_damping_injection=0.0)  # the bound alone (nor the out-of-reach caps)
    lags = {}
    for share in (0.0, None):
        scen = TeleopScenario.from_source(talos, "push_pull", duration=2.0, speed=2.0, name="push_pull_x2")
        ctrl = Probe(talos, ActuationMode.SPD, scen.spec.control_dt, taskset=spec, arm_torque_share=share,
                     reach_cap=False)
        result = run(scen, ctrl, robot=talos, out=tmp_path / str(share))
        assert not result.summary["fell"]
        lags[share] = ctrl.lag
    assert lags[0.0] > 0.2
    assert lags[None] < 0.16


def test_a_bad_arm_torque_share_is_a_config_error(talos, tmp_path):
    """The share comes from the task set (`arm_torque_share:`, TALOS' 0.7); a negative one, given to the controller
    or in a task-set file, is a one-line ConfigError naming the key (and the file)."""
    import yaml

    from wbcbench.controllers.taskset import load_taskset, taskset_path

    assert TSIDTeleop(talos, ActuationMode.SPD, 1e-3).arm_torque_share == 0.7
    with pytest.raises(ConfigError, match="arm_torque_share"):
        TSIDTeleop(talos, ActuationMode.SPD, 1e-3, arm_torque_share=-0.1)
    bad = tmp_path / "teleop.yaml"
    bad.write_text(yaml.safe_dump({**yaml.safe_load(taskset_path(talos, "teleop").read_text()),
                                   "arm_torque_share": -0.1}))
    with pytest.raises(ConfigError, match="arm_torque_share") as exc:
        load_taskset(bad, talos)
    assert "teleop.yaml" in str(exc.value) and "\n" not in str(exc.value)


def test_inject_damping_adds_c_times_the_tracking_velocity_error():
    v_cmd = np.array([1.0, 2.0, -1.0])
    v_meas = np.zeros(9)
    v_meas[6:] = [0.5, 2.0, 0.0]
    inject_damping(v_cmd, v_meas, np.array([6, 8]), 4.0)
    # joint 0: 1 + 4 (1 - 0.5); joint 1 not listed; joint 2: -1 + 4 (-1 - 0)
    assert np.allclose(v_cmd, [3.0, 2.0, -5.0])


def test_arm_damping_injection_comes_from_the_task_set(talos, tmp_path):
    import yaml

    from wbcbench.controllers.taskset import load_taskset, taskset_path

    assert TSIDTeleop(talos, ActuationMode.SPD, 1e-3).arm_damping_injection == 6.0
    assert TSIDTeleop(talos, ActuationMode.TORQUE, 1e-3).arm_damping_injection == 0.0  # torque mode: no servos
    data = yaml.safe_load(taskset_path(talos, "teleop").read_text())
    data["arm_damping_injection"] = -1.0
    bad = tmp_path / "teleop.yaml"
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="arm_damping_injection"):
        load_taskset(bad, talos)


def test_damping_injection_keeps_the_measured_arm_closer_to_the_integrated_arm(talos, tmp_path):
    """The joint servos' damping is 0.01 of their stiffness: an arm that lags the integrated one and runs after it
    at saturated torque overshoots it (on a public punch-in-place capture, into the hips and thighs). The arms'
    velocity references v_int + c (v_int - v) damp that error (1 + c) times as much: the shipped bimanual
    push-pull replayed twice as fast, its arms' lag behind the integrated arms (median and largest over the
    ticks) smaller with the task set's c = 6 than with c = 0, and the command's arm velocities are those
    references."""
    from dataclasses import replace

    from wbcbench.controllers.teleop import teleop_taskset

    idx = arm_joints(talos)

    class Probe(TSIDTeleop):
        def step(self, meas, refs):
            cmd = super().step(meas, refs)
            self.lags.append(float(np.abs(self.q_int[idx + 1] - meas.q[idx + 1]).max()))
            v = self.v_int[idx]
            self.worst = max(self.worst, float(np.abs(
                cmd.v[idx - 6] - (v + self.arm_damping_injection * (v - meas.v[idx]))).max()))
            return cmd

    lags = {}
    for c in (0.0, 6.0):
        scen = TeleopScenario.from_source(talos, "push_pull", duration=2.0, speed=2.0, name="push_pull_x2")
        spec = replace(teleop_taskset(talos), arm_damping_injection=c)
        ctrl = Probe(talos, ActuationMode.SPD, scen.spec.control_dt, taskset=spec)
        ctrl.lags, ctrl.worst = [], 0.0
        result = run(scen, ctrl, robot=talos, out=tmp_path / str(c))
        assert not result.summary["fell"]
        assert ctrl.worst < 1e-12
        lags[c] = np.median(ctrl.lags), np.max(ctrl.lags)
    # measured: median 0.0143 -> 0.0098 rad, largest 0.117 -> 0.099 rad
    assert lags[6.0][0] < 0.8 * lags[0.0][0], lags
    assert lags[6.0][1] < 0.9 * lags[0.0][1], lags
