"""The sensor model: ideal is the identity, each imperfection has the statistics its profile says, runs are
reproducible, and the base estimator (IMU + leg kinematics) stays close to the truth on a walk."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from wbcbench.runner import run
from wbcbench.sensing import SensorProfile, load_sensor_profile, make_sensor_model
from wbcbench.side import Side
from wbcbench.sim.simulator import Simulator
from wbcbench.types import Command


def _ticks(robot, n):
    """n measurements of TALOS standing in torque-free SPD at its posture (a real closed loop)."""
    sim = Simulator(robot, mode="spd")
    out = []
    for _ in range(n):
        sim.apply(Command(q=robot.q0[7:], v=np.zeros(robot.na)))
        sim.step()
        out.append(sim.measure())
    return out


def test_ideal_is_the_identity_and_logs_are_unchanged(talos, tmp_path):
    model = make_sensor_model(None, talos, 1e-3)
    meas = _ticks(talos, 1)[0]
    assert model.ideal and model.measure(meas) is meas
    a = run("stand", "tsid-torque", duration=0.3, out=tmp_path / "a")
    b = run("stand", "tsid-torque", duration=0.3, out=tmp_path / "b", sensors="ideal")
    for k in a.log:
        if k != "controller_time_us":
            np.testing.assert_array_equal(a.log[k], b.log[k], err_msg=k)


def test_noise_bias_quantisation_statistics(talos):
    p = SensorProfile(name="t", force_noise=2.0, force_bias=5.0, gyro_noise=0.01, encoder_resolution=1e-3)
    model = make_sensor_model(p, talos, 1e-3, seed=3)
    true = _ticks(talos, 400)
    out = [model.measure(m) for m in true]
    df = np.array([o.ft_force[Side.LEFT] - m.ft_force[Side.LEFT] for o, m in zip(out, true)])
    bias = df.mean(axis=0)
    np.testing.assert_allclose(bias, model.ft_bias[Side.LEFT][:3], atol=0.4)   # 4 sigma of the mean
    assert np.std(df - bias, axis=0) == pytest.approx([2.0] * 3, rel=0.15)
    dg = np.array([o.gyro - m.gyro for o, m in zip(out, true)])
    assert np.std(dg, axis=0) == pytest.approx([0.01] * 3, rel=0.15)
    q = np.array([o.q[7:] for o in out])
    np.testing.assert_allclose(q / 1e-3, np.round(q / 1e-3), atol=1e-9)
    assert np.abs(q - np.array([m.q[7:] for m in true])).max() <= 0.5e-3 + 1e-12
    again = make_sensor_model(p, talos, 1e-3, seed=3)
    np.testing.assert_array_equal(again.measure(true[0]).ft_force[Side.LEFT], out[0].ft_force[Side.LEFT])


def test_encoder_calibration_offsets(talos):
    """`encoders.offset`: a constant per-joint offset of the given std, the base untouched; drawn from a generator
    of its own, so that every other term draws exactly as without it."""
    from dataclasses import replace

    p = SensorProfile(name="t", force_noise=2.0, gyro_noise=0.01)
    true = _ticks(talos, 50)
    plain = make_sensor_model(p, talos, 1e-3, seed=3)
    off = make_sensor_model(replace(p, encoder_offset=0.02), talos, 1e-3, seed=3)
    a, b = [plain.measure(m) for m in true], [off.measure(m) for m in true]
    d = np.array([y.q[7:] - x.q[7:] for x, y in zip(a, b)])
    np.testing.assert_allclose(d, np.broadcast_to(off.encoder_offset, d.shape), atol=1e-15)
    assert plain.encoder_offset is None and np.std(off.encoder_offset) == pytest.approx(0.02, rel=0.3)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.q[:7], y.q[:7])
        np.testing.assert_array_equal(x.ft_force[Side.LEFT], y.ft_force[Side.LEFT])
        np.testing.assert_array_equal(x.gyro, y.gyro)
    assert not replace(p, encoder_offset=0.01).ideal and SensorProfile(encoder_offset=0.01).ideal is False


def test_latency_and_drops(talos):
    true = _ticks(talos, 60)
    model = make_sensor_model(SensorProfile(name="d", latency=0.005), talos, 1e-3)
    out = [model.measure(m) for m in true]
    for k in range(5, 60):
        np.testing.assert_array_equal(out[k].q, true[k - 5].q)
        assert out[k].t == true[k].t   # the controller's clock is not delayed
    model = make_sensor_model(SensorProfile(name="x", drop_rate=0.3), talos, 1e-3, seed=1)
    out = [model.measure(m) for m in true]
    repeats = sum(out[k] is out[k - 1] or np.array_equal(out[k].q, out[k - 1].q) for k in range(1, 60))
    assert model.n_dropped == repeats and 8 <= model.n_dropped <= 30


def test_base_estimator_on_a_walk(tmp_path):
    """walk-20cm (quick) under talos-like sensing, base estimated from IMU + leg kinematics: no fall, base error
    reported and bounded (measured: 2.1 cm rms, 4.7 cm max, 0.009 rad with TSID torque's wrench axis weights
    (1, 1, 0.1, 2, 2, 2); 1.0 cm rms, 2.3 cm max with every axis at 1: the README's TSID torque section)."""
    res = run("walk-20cm-quick", "tsid-torque", out=tmp_path / "w", sensors="talos-like")
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    err = s["metrics"]["base_estimate_error"]
    assert err["position_max_m"] < 0.06 and err["position_rms_m"] < 0.03 and err["orientation_max_rad"] < 0.02
    assert err["position_max_m"] > 1e-4  # it is an estimate, not the simulator's state
    assert s["sensors"]["profile"] == "talos-like"


def test_profiles_and_bad_input(tmp_path):
    assert load_sensor_profile("ideal").ideal and not load_sensor_profile("talos-like").ideal
    out = subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", "stand", "-c", "joint-pd", "--duration",
                          "0.01", "--sensors", "talos-lik", "--out", str(tmp_path / "r")], capture_output=True,
                         text=True)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1
    assert "talos-like" in out.stderr and "--sensors" in out.stderr
    bad = tmp_path / "s.yaml"
    bad.write_text("name: bad\nimu: {gyro_noise: -1}\n")
    out = subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", "stand", "-c", "joint-pd", "--duration",
                          "0.01", "--sensors", str(bad), "--out", str(tmp_path / "r")], capture_output=True, text=True)
    assert out.returncode == 2 and "imu.gyro_noise" in out.stderr and str(bad) in out.stderr, out.stderr
