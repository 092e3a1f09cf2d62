"""Fault injection: each fault gives its documented safe behaviour and a log entry (wbcbench/faults.py)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from wbcbench.controllers.base import make_controller
from wbcbench.faults import Fault
from wbcbench.runner import run


def _events(summary):
    return [(e["event"], e["type"]) for e in summary["faults"]["events"]]


def test_sensor_nan_is_held_by_the_guard_then_safe_stop(talos, tmp_path):
    ctrl = make_controller("tsid-torque", talos, None, 1e-3)
    seen = []
    step = ctrl.step
    ctrl.step = lambda meas, refs: (seen.append(bool(np.isfinite(meas.ft_force[next(iter(meas.ft_force))]).all())),
                                    step(meas, refs))[1]
    res = run("stand", ctrl, robot=talos, duration=1.2, out=tmp_path / "r",
              faults=[Fault("sensor_nan", 0.5, 0.2, "ft_left")])
    s = res.summary
    assert all(seen), "a NaN reached the controller"
    assert not s["fell"]
    assert _events(s) == [("start", "sensor_nan"), ("safe_stop", "measurement invalid"), ("end", "sensor_nan")]
    assert s["faults"]["guard_held_ticks"] == 200 and s["faults"]["safe_stop_t"] == pytest.approx(0.599, abs=2e-3)
    held, stop = res.log["faults.guard_held"], res.log["faults.safe_stop"]
    t = res.log["t"]
    assert held[(t > 0.51) & (t < 0.69)].all() and not held[t < 0.49].any()
    assert stop[t > 0.62].all() and not stop[t < 0.59].any()  # the safe stop stays on to the end


def test_qp_failure_uses_the_controllers_fallback(tmp_path):
    res = run("stand", "tsid-torque", duration=1.0, out=tmp_path / "r", faults=[Fault("qp_failure", 0.4, 0.05)])
    s = res.summary
    assert not s["fell"] and s["controller_status"]["qp_fallback_ticks"] == 50
    assert _events(s) == [("start", "qp_failure"), ("end", "qp_failure")]
    assert res.log["qp_status"][(res.log["t"] > 0.41) & (res.log["t"] < 0.45)].min() == 2  # QP_FALLBACK


def test_locked_and_cut_joints(talos, tmp_path):
    """On the sway the arms move (angular momentum task: arm_left_2 up to 0.06 rad/s); locked, it stays within
    1e-4 rad/s; a cut joint gets no torque."""
    faults = [Fault("joint_locked", 0.5, None, "arm_left_2_joint")]
    locked = run("sway", "tsid-torque", duration=1.5, out=tmp_path / "l", faults=faults)
    free = run("sway", "tsid-torque", duration=1.5, out=tmp_path / "f")
    t = locked.log["t"]
    assert np.abs(locked.log["v.arm_left_2_joint"][t > 0.6]).max() < 1e-4
    assert np.abs(free.log["v.arm_left_2_joint"][t > 0.6]).max() > 0.01
    assert not locked.summary["fell"]
    res = run("sway", "tsid-position", duration=1.0, out=tmp_path / "c",
              faults=[Fault("joint_cut", 0.5, None, "arm_left_4_joint")])
    tau = res.log["tau.arm_left_4_joint"]
    t = res.log["t"]
    assert np.abs(tau[t > 0.51]).max() < 1e-9 < np.abs(tau[t < 0.49]).max()
    assert res.summary["faults"]["events"][0]["type"] == "joint_cut"


def test_frozen_sensor_is_flagged(tmp_path):
    """A reading that stops changing is flagged after 50 ticks, and the flag goes when it changes again."""
    res = run("sway", "tsid-torque", duration=1.0, out=tmp_path / "r", faults=[Fault("sensor_freeze", 0.3, 0.4, "imu")])
    frozen, t = res.log["faults.sensor_frozen"], res.log["t"]
    assert frozen[(t > 0.36) & (t < 0.69)].all() and not frozen[t < 0.34].any() and not frozen[t > 0.72].any()
    assert not res.summary["fell"]


@pytest.mark.parametrize("spec,needle", [("sensor_nan:gps@1", "gps"), ("joint_locked:knee@1", "knee"),
                                         ("qp_failure", "TYPE[:TARGET]@START"), ("warp@1", "warp")])
def test_bad_fault_option(tmp_path, spec, needle):
    out = subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", "stand", "-c", "joint-pd", "--duration", "0.01",
                          "--fault", spec, "--out", str(tmp_path / "r")], capture_output=True, text=True)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1 and needle in out.stderr, out.stderr


def test_passive_joint_only_damps(talos, tmp_path):
    """A passive joint's actuator gives only the damping torque -kd v of the profile's gain, whatever the controller
    commands (inria_wbc's PASSIVE); the run goes on and the event is logged."""
    joint = "arm_left_4_joint"
    res = run("sway", "tsid-torque", duration=1.0, out=tmp_path / "p",
              faults=[Fault("joint_passive", 0.5, None, joint)])
    kd = talos.profile.position_gains.resolve(talos.joint_names, talos.profile.file)[1][talos.joint_names.index(joint)]
    t, tau, v = res.log["t"], res.log[f"tau.{joint}"], res.log[f"v.{joint}"]
    after = np.flatnonzero(t > 0.51)
    # the torque of a step comes from the velocity at its start: the state logged one tick before
    np.testing.assert_allclose(tau[after], -kd * v[after - 1], rtol=1e-9, atol=1e-9)
    assert np.abs(tau[after]).max() > 1e-3  # the joint moves, so the damping is really there
    cmd = res.log[f"tau_cmd.{joint}"]
    assert np.abs(cmd[after] - tau[after]).max() > 0.1  # and the command is ignored
    assert res.summary["faults"]["events"][0]["type"] == "joint_passive"
    assert not res.summary["fell"]
