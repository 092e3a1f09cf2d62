"""The DART engine: the same robot as pinocchio's (kinematics, mass matrix, bias forces through the bridge), its
sensors consistent with its contacts, the controllers running on it, the engine registry open to plugins, and its
errors one line each."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.errors import ConfigError, UnknownNameError
from wbcbench.robots import Side
from wbcbench.scene import Terrain
from wbcbench.sim.engines import available_engines, engine_class, make_simulator
from wbcbench.types import Command

dart = pytest.importorskip("dartpy", reason="the dart extra (pip install 'wbcbench[dart]') is not installed")
from wbcbench.sim.dart_engine import DartSimulator  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def _random_state(robot, rng):
    lo, hi = robot.position_limits
    q = robot.q0.copy()
    q[7:] = rng.uniform(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo))
    q[:3] = rng.normal(size=3) + [0, 0, 3.0]
    q[3:7] = pin.Quaternion(pin.exp3(rng.normal(size=3))).coeffs()
    return q, rng.normal(size=robot.nv)


def _dart_to_pin_velocity(sim, q) -> np.ndarray:
    """J with v_pin = J v_dart: DART's free joint has world-frame (angular, linear), pinocchio local (linear,
    angular); joints matched by name."""
    b = sim.bridge
    nv = sim.robot.nv
    P = np.zeros((nv, b.ndof))
    P[3:6, 0:3] = P[0:3, 3:6] = np.eye(3)
    P[b.pin_v_idx, b.dart_idx] = 1.0
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    J = np.eye(nv)
    J[0:3, 0:3] = J[3:6, 3:6] = R.T
    return J @ P


@pytest.fixture(params=["talos", "g1"])
def robot(request, talos, g1):
    return {"talos": talos, "g1": g1}[request.param]


def test_state_round_trip_and_frames_match_pinocchio(robot):
    sim = DartSimulator(robot, Terrain(floor=False), "torque")
    m, d = robot.model, robot.model.createData()
    rng = np.random.default_rng(0)
    for _ in range(3):
        q, v = _random_state(robot, rng)
        sim.reset(q, v)
        assert np.allclose(sim.true_q(), q, atol=1e-13) and np.allclose(sim.true_v(), v, atol=1e-12)
        pin.framesForwardKinematics(m, d, q)
        for side in Side:
            frame = robot.profile.feet[side].frame
            body, M = sim._body_and_placement(frame)
            T = body.getWorldTransform()
            placed = pin.SE3(np.asarray(T.rotation()), np.asarray(T.translation())) * M
            assert np.allclose(placed.homogeneous, d.oMf[m.getFrameId(frame)].homogeneous, atol=1e-10)


def test_mass_matrix_and_bias_forces_match_pinocchio_without_armature(robot):
    """DART 6 has no joint armature: its mass matrix is pinocchio's with the rotor inertia removed, to 1e-8."""
    sim = DartSimulator(robot, Terrain(floor=False), "torque")
    model = robot.model.copy()
    model.armature[:] = 0.0
    data = model.createData()
    rng = np.random.default_rng(1)
    for _ in range(3):
        q, v = _random_state(robot, rng)
        sim.reset(q, v)
        J = _dart_to_pin_velocity(sim, q)
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        assert np.abs(J.T @ M @ J - np.asarray(sim.skel.getMassMatrix())).max() < 1e-8
        g = pin.computeGeneralizedGravity(model, data, q)
        assert np.abs(J.T @ g - np.asarray(sim.skel.getGravityForces())).max() < 1e-8
        # the bias in DART's coordinates: pinocchio's rnea at the acceleration that DART's zero acceleration is
        # (the base's world-frame coordinates have their own time derivative: compare M ddq + h on a random ddq)
        ddq_dart = rng.normal(size=sim.bridge.ndof)
        sim.skel.setAccelerations(ddq_dart)
        tau_dart = np.asarray(sim.skel.getMassMatrix()) @ ddq_dart + np.asarray(sim.skel.getCoriolisAndGravityForces())
        # pinocchio: a_pin = J ddq_dart + dJ/dt v_dart, dJ/dt from the base rotation's rate
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        w_local = v[3:6]
        v_dart = np.linalg.solve(J, v)
        Jdot = np.zeros_like(J)
        Jdot[0:3] = -pin.skew(w_local) @ J[0:3]
        Jdot[3:6] = -pin.skew(w_local) @ J[3:6]
        a_pin = J @ ddq_dart + Jdot @ v_dart
        tau_pin = pin.rnea(model, data, q, v, a_pin)
        assert np.abs(J.T @ tau_pin - tau_dart).max() < 1e-7, R


def test_standing_servo_sensors_agree_with_contacts(talos):
    """Held at half-sitting by the position servos (no balance controller: on rigid contacts without armature the
    robot rocks a little from foot to foot): averaged over 0.5 s the soles carry the robot's weight, each ankle
    F/T reads the contact force less the foot's weight (-R F_s = F - m_foot g), the IMU's accelerometer reads
    gravity; the servo torques stay within the effort limits."""
    sim = DartSimulator(talos, Terrain(), "position")
    sim.apply(Command(q=talos.q0[7:].copy(), v=np.zeros(talos.na)))
    sim.step(500)
    m, d = talos.model, talos.model.createData()
    total, foot_weight, lateral, acc = [], [], [], []
    for _ in range(500):
        sim.step(1)
        w = sim.contact_wrench_array()
        total.append(w[:, 2].sum())
        meas = sim.measure()
        pin.framesForwardKinematics(m, d, meas.q)
        for k, side in enumerate(Side):
            R = d.oMf[m.getFrameId(talos.profile.feet[side].ft_sensor_frame)].rotation
            f_contact = -R @ meas.ft_force[side]
            foot_weight.append(w[k, 2] - f_contact[2])
            lateral.append(np.abs(f_contact[:2] - w[k, :2]).max())
        R_imu = pin.Quaternion(meas.imu_quat[3], *meas.imu_quat[:3]).toRotationMatrix()
        acc.append(R_imu @ meas.accelerometer)
        assert np.all(np.abs(sim.applied_torque()) <= talos.effort_limit + 1e-9)
    mg = pin.computeTotalMass(talos.model) * 9.81
    assert abs(np.mean(total) - mg) < 0.02 * mg
    assert not sim.fall_status().fell
    assert 14.0 < np.median(foot_weight) < 17.5  # the foot below the sensor: 1.6 kg on TALOS
    assert np.median(lateral) < 5.0
    assert np.allclose(np.mean(acc, axis=0), [0, 0, 9.81], atol=0.25)  # the rocking averages out only roughly


def test_free_fall_follows_gravity(talos):
    sim = DartSimulator(talos, Terrain(floor=False), "torque")
    q, _ = _random_state(talos, np.random.default_rng(3))
    sim.reset(q, np.zeros(talos.nv))
    sim.step(100)
    com0 = pin.centerOfMass(talos.model, talos.model.createData(), q)
    com1 = pin.centerOfMass(talos.model, talos.model.createData(), sim.true_q())
    assert abs(com1[2] - com0[2] + 0.5 * 9.81 * 0.1 ** 2) < 2e-3
    assert np.allclose(com1[:2], com0[:2], atol=1e-6)


@pytest.mark.parametrize("controller", ["tsid-torque", "ik", "tsid-position"])
def test_controllers_stand_on_dart(talos, controller, tmp_path):
    from wbcbench.runner import run

    res = run("stand", controller, talos, duration=1.0, out=tmp_path / "r", engine="dart")
    assert not res.summary["fell"]
    assert res.summary["metrics"]["com_error_m"]["x"]["peak"] < 0.005
    assert json.loads((tmp_path / "r" / "config.json").read_text())["engine"] == "dart"


def test_tsid_torque_walks_on_dart(talos, tmp_path):
    from wbcbench.runner import run

    res = run("walk-20cm-quick", "tsid-torque", talos, out=tmp_path / "w", engine="dart")
    s = res.summary
    assert not s["fell"]
    assert abs(s["metrics"]["distance_m"] - s["metrics"]["planned_distance_m"]) < 0.02
    assert s["metrics"]["zmp_error_m"]["x"]["mean"] < 0.01


def test_engine_registry_and_errors(talos):
    assert available_engines()[:2] == ["mujoco", "dart"]
    assert engine_class("dart") is DartSimulator
    with pytest.raises(UnknownNameError, match="unknown engine 'dratt'.*did you mean 'dart'"):
        engine_class("dratt")
    with pytest.raises(ConfigError, match="model error .* MuJoCo models only"):
        make_simulator("dart", talos, Terrain(), "torque", None, (), model_error=object())
    from wbcbench.sim.model import SimOptions

    with pytest.raises(ConfigError, match="'physical' .* needs the mujoco engine"):  # a feature DART cannot build
        make_simulator("dart", talos, Terrain(), "torque", SimOptions(self_collision="physical"))
    assert "armature" in DartSimulator.COMPARISON_NOTE


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "wbcbench.cli", *args], capture_output=True, text=True, env=env,
                          cwd=ROOT)


def test_cli_engine_errors_are_one_line(tmp_path):
    out = _cli("run", "stand", "-c", "tsid-torque", "--engine", "bullet3", "-d", "0.01", "--out", str(tmp_path / "a"))
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1 and "unknown engine" in out.stderr


def test_a_third_engine_from_an_entry_point_is_listed_and_runs_stand(tmp_path):
    """A tiny engine package (MuJoCo with the Euler integrator, as a user's wrapper would be) pip-installed into a
    directory of its own: `list` shows it with its distribution and `run --engine` uses it."""
    pkg = tmp_path / "pkg"
    (pkg / "src" / "wbcbench_euler").mkdir(parents=True)
    (pkg / "src" / "wbcbench_euler" / "__init__.py").write_text(
        "from dataclasses import replace\n"
        "from wbcbench.sim.model import SimOptions\n"
        "from wbcbench.sim.simulator import Simulator\n\n"
        "class EulerMuJoCo(Simulator):\n"
        "    engine = 'mujoco-euler'\n\n"
        "    def __init__(self, robot, terrain, mode, options, pushes, model_error):\n"
        "        super().__init__(robot, terrain, mode, replace(options or SimOptions(), integrator='euler'),\n"
        "                         pushes, model_error)\n")
    (pkg / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["setuptools>=77"]\nbuild-backend = "setuptools.build_meta"\n'
        '[project]\nname = "wbcbench-euler"\nversion = "0.0.1"\n'
        '[project.entry-points."wbcbench.engines"]\nmujoco-euler = "wbcbench_euler:EulerMuJoCo"\n'
        '[tool.setuptools.packages.find]\nwhere = ["src"]\n')
    site = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", "install", "--no-deps",
                    "--no-build-isolation", "--target", str(site), str(pkg)], check=True, capture_output=True)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(site), os.environ.get("PYTHONPATH")]))}
    out = _cli("list", env=env)
    assert out.returncode == 0, out.stderr
    line = next(l for l in out.stdout.splitlines() if l.startswith("engines:"))
    assert "mujoco-euler [wbcbench-euler]" in line
    out = _cli("run", "stand", "-c", "tsid-torque", "--engine", "mujoco-euler", "-d", "0.5", "--quiet",
               "--out", str(tmp_path / "r"), env=env)
    assert out.returncode == 0, out.stderr
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert not s["fell"]
    assert json.loads((tmp_path / "r" / "config.json").read_text())["engine"] == "mujoco-euler"


def test_position_servo_is_clipped_to_the_effort_limit(talos):
    """The position servo's torque never exceeds a joint's effort limit (MuJoCo's actuator force range), even with
    a reference far from the state."""
    sim = DartSimulator(talos, Terrain(), "position")
    q_ref = talos.q0[7:].copy()
    knee = talos.joint_names.index("leg_left_4_joint")
    q_ref[knee] += 0.5
    sim.apply(Command(q=q_ref, v=np.zeros(talos.na)))
    sim.step(5)
    tau = sim.applied_torque()
    assert np.all(np.abs(tau) <= talos.effort_limit + 1e-9)
    assert abs(tau[knee]) == pytest.approx(talos.effort_limit[knee])


def test_teleoperation_on_dart(tmp_path):
    """Paper 004's engine: a shipped recording replayed through tsid-teleop (SPD low level) on DART, self-collisions
    counted on the kinematic copy: no fall, the hands within the paper's Table II mean error."""
    from wbcbench.teleop.commands import run_session

    res = run_session("reach_forward", repulsors=False, stabilizer=False, duration=2.0, start=0.8,
                      out=tmp_path / "t", engine="dart")
    s = res.summary
    assert not s["fell"]
    assert json.loads((tmp_path / "t" / "config.json").read_text())["engine"] == "dart"
    assert s["metrics"]["hand_position_error_m"]["mean"] < 0.034
    assert s["metrics"]["self_collisions"] == 0


def test_an_engine_whose_package_is_missing_says_how_to_install_it(monkeypatch):
    import importlib.util

    from wbcbench.sim import engines

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "dartpy" else real(name, *a))
    with pytest.raises(ConfigError, match=r"engine 'dart' needs the package 'dartpy': pip install 'wbcbench\[dart\]'"):
        engines.engine_class("dart")
    assert engines.engine_label("dart") == "dart (needs dartpy)"
