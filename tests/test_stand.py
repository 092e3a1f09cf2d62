"""Standing in simulation: the joint-pd controller keeps TALOS (three modes) and G1 up, IK keeps the G1 on one foot;
a failing run keeps its log."""

import json

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.controllers.base import Controller, register
from wbcbench.recorder import read_log
from wbcbench.runner import run
from wbcbench.side import Side
from wbcbench.sim.model import ActuationMode


@pytest.mark.parametrize("mode", ["torque", "position", "spd"])
def test_talos_stands_10s(talos, tmp_path, mode):
    res = run("stand", "joint-pd", talos, mode=mode, duration=10.0, out=tmp_path)
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    assert s["sim_time_s"] == pytest.approx(10.0)
    assert s["metrics"]["base_height_max_deviation_m"] < 0.02
    # the contact forces carry the robot's weight at the end
    fz = res.log["contact_left.fz"][-1] + res.log["contact_right.fz"][-1]
    assert fz == pytest.approx(talos.mass * 9.81, rel=0.02)
    summary = json.loads((tmp_path / "summary.json").read_text())
    for key in ("robot", "scenario", "controller", "mode", "fell", "fall_reason", "sim_time_s", "wall_time_s",
                "step_time_us", "metrics"):
        assert key in summary
    assert set(summary["step_time_us"]) >= {"median", "p99", "max"}
    assert len(read_log(tmp_path / "log.parquet")["t"]) == 10000


def test_g1_stands_10s_torque(g1, tmp_path):
    res = run("stand", "joint-pd", g1, mode="torque", duration=10.0, out=tmp_path)
    assert not res.summary["fell"], res.summary["fall_reason"]
    assert res.summary["metrics"]["base_height_max_deviation_m"] < 0.02


def test_g1_one_foot_ik(g1, tmp_path):
    """The G1 on one foot with IK in position mode (fell at 3.3 s when the CoM shift took the file's 1.5 s): 2 s
    on the left foot, the right one lifted, the CoM back over the 7 cm wide sole."""
    res = run("one-foot", "ik", g1, duration=4.0, out=tmp_path)
    assert not res.summary["fell"], res.summary["fall_reason"]
    log, t = res.log, res.log["t"]
    assert log["contact_right.fz"][t > 2.5].max() < 1.0
    assert log["contact_left.fz"][-1] == pytest.approx(g1.mass * 9.81, rel=0.05)
    data = g1.model.createData()
    pin.framesForwardKinematics(g1.model, data, g1.q0)
    sole_y = data.oMf[g1.sole_frame_id(Side.LEFT)].translation[1]
    assert abs(log["com.y"][-1] - sole_y) < 0.02


def test_talos_survives_100N_lateral_push(talos, tmp_path):
    res = run("push", "joint-pd", talos, mode="torque", out=tmp_path)
    assert not res.summary["fell"], res.summary["fall_reason"]
    # the push did act: the base moved sideways during/after it
    y = res.log["q.y"]
    t = res.log["t"]
    assert np.abs(y[(t > 1.0) & (t < 2.0)] - y[0]).max() > 1e-3


def test_a_fall_is_detected_and_logged(talos, tmp_path):
    """No torque at all: TALOS collapses; the run stops, says why, and keeps its log up to the fall."""
    res = run("stand", "zero-torque-test", talos, duration=5.0, out=tmp_path)
    s = res.summary
    assert s["fell"] and s["fall_reason"]
    assert s["sim_time_s"] < 5.0
    log = read_log(tmp_path / "log.parquet")
    assert len(log["t"]) == round(s["sim_time_s"] / 1e-3)


def test_a_crashing_controller_keeps_the_log(talos, tmp_path):
    res = run("stand", "crash-test", talos, duration=2.0, out=tmp_path)
    s = res.summary
    assert s["fell"] and "boom" in s["fall_reason"]
    assert len(read_log(tmp_path / "log.parquet")["t"]) == 1500
    assert (tmp_path / "error.txt").exists()


@register
class _ZeroTorque(Controller):
    name = "zero-torque-test"
    modes = (ActuationMode.TORQUE,)

    def reset(self, meas, refs):
        pass

    def step(self, meas, refs):
        from wbcbench.types import Command
        return Command(tau=np.zeros(self.robot.na))


@register
class _Crash(_ZeroTorque):
    name = "crash-test"

    def __init__(self, robot, mode, dt):
        super().__init__(robot, mode, dt)
        from wbcbench.controllers.joint_pd import JointPD
        self.inner = JointPD(robot, mode, dt)
        self.n = 0

    def step(self, meas, refs):
        self.n += 1
        if self.n > 1500:
            raise RuntimeError("boom")
        return self.inner.step(meas, refs)


def test_runs_are_deterministic(talos, tmp_path):
    """The same scenario and controller twice give bit-identical logs (no hidden state, no randomness)."""
    a = run("push", "tsid-torque", talos, duration=1.2, out=tmp_path / "a").log
    b = run("push", "tsid-torque", talos, duration=1.2, out=tmp_path / "b").log
    for key in a:
        if key == "controller_time_us":
            continue
        assert np.array_equal(a[key], b[key], equal_nan=True), key


def test_the_start_posture_rests_on_both_edges_of_each_sole(talos, tmp_path):
    """TALOS' half_sitting turns both ankle rolls by -1.7 mrad: with the sole origins at z = 0 each sole started on
    one edge (the other 0.22 mm up) and for the first 4 ms its centre of pressure sat at that edge (ankle F/T
    mx / fz 0.039 m, the ZMP 6 cm to the side: the y peak of every paper scene). The base now puts the highest sole
    corner at z = 0, so both edges touch from the start."""
    d = talos.model.createData()
    pin.framesForwardKinematics(talos.model, d, talos.q0)
    z = [float(d.oMf[talos.sole_frame_id(s)].act(c)[2]) for s in Side for c in talos.profile.sole.corners]
    assert max(z) == pytest.approx(0.0, abs=1e-12)
    assert min(z) < -1e-4            # the tilt is still there (the posture is the SRDF's)
    res = run("stand", "tsid-torque", talos, duration=0.02, out=tmp_path)
    log = res.log
    for s in ("left", "right"):  # each sole's centre of pressure (below the ankle) near its middle from the start
        assert np.all(np.abs(log[f"ft_{s}.mx"] / log[f"ft_{s}.fz"]) < 0.02), s
