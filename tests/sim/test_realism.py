"""The realism switch (wbcbench/sim/realism): each hidden mechanism acts, the controller's view keeps the nominal
layout, bad presets are one-line errors, and without the switch nothing changes."""

import json
import math
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from wbcbench.config import Section
from wbcbench.errors import ConfigError
from wbcbench.robots import load_robot
from wbcbench.sim.model import SimOptions
from wbcbench.sim.realism import TorqueLoop as LoopSpec, load_realism, parse_realism
from wbcbench.sim.simulator import Simulator, TorqueLoop
from wbcbench.types import Command


@pytest.fixture(scope="module")
def robot():
    return load_robot("talos")


def preset(robot, data, file="test-preset.yaml"):
    return parse_realism(Section(data, file), robot)


def _jid(sim, name):
    return mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_JOINT, name)


def _qadr(sim, name):
    return int(sim.model.jnt_qposadr[_jid(sim, name)])


def test_shipped_preset_parses_with_sources(robot):
    r = load_realism("talos-real", robot)
    i = robot.joint_names.index("leg_left_4_joint")
    assert r.stiffness[i] > 0 and r.coulomb[i] > 0 and r.sensors == "talos-like"
    assert r.hip is not None and r.hip.stiffness == 973.0
    assert r.torque_loop is not None and r.torque_loop.delay > 0
    text = (load_realism.__globals__["PRESET_DIR"] / "talos-real.yaml").read_text()
    assert "UNPUBLISHED" in text and "973" in text  # values carry their source or say they have none


def test_drive_deflection_is_torque_over_stiffness_and_unseen_by_the_encoder(robot):
    """Standing in position mode (servo on the motor side), loaded by the robot's weight: at rest each drive's
    deflection equals the transmitted torque over its stiffness, and the link's angle relative to its parent is
    the encoder's reading plus that deflection."""
    K = 30000.0
    r = preset(robot, {"actuators": {"leg_*": {"stiffness": K, "damping": 200.0}}})
    sim = Simulator(robot, mode="position", options=SimOptions(realism=r))
    sim.apply(Command(q=robot.q0[7:].copy(), v=np.zeros(robot.na)))
    sim.step(1500)
    assert not sim.fall_status().fell
    tau = sim.applied_torque()
    meas = sim.measure()
    loaded = [n for i, n in enumerate(robot.joint_names) if n.startswith("leg_") and abs(tau[i]) > 20.0]
    assert {"leg_left_4_joint", "leg_right_4_joint"} <= set(loaded)  # the knees carry the robot's weight
    for name in loaded:
        i = robot.joint_names.index(name)
        delta = sim.data.qpos[_qadr(sim, f"{name}:drive")]
        # the link lags the motor by torque / stiffness (deflection = link - motor)
        assert -delta == pytest.approx(tau[i] / K, rel=0.02, abs=2e-6)
        # the encoder reads the motor side
        motor = sim.data.qpos[_qadr(sim, name)]
        assert meas.q[7 + i] == motor
        assert abs(delta) > 1e-4
    # the link side: the knee link's rotation relative to the thigh is motor + deflection about the joint axis
    m, d = sim.model, sim.data
    mujoco.mj_kinematics(m, d)  # the link poses of the current qpos (mj_step leaves those of the step before)
    j = _jid(sim, "leg_left_4_joint")
    child, parent = m.jnt_bodyid[j], m.body_parentid[m.jnt_bodyid[j]]
    R = d.xmat[parent].reshape(3, 3).T @ d.xmat[child].reshape(3, 3)
    R0 = np.zeros(9)
    mujoco.mju_quat2Mat(R0, m.body_quat[child])
    Rrel = R0.reshape(3, 3).T @ R
    axis = m.jnt_axis[j]
    angle = math.atan2(np.dot(axis, [Rrel[2, 1] - Rrel[1, 2], Rrel[0, 2] - Rrel[2, 0], Rrel[1, 0] - Rrel[0, 1]]) / 2,
                       (np.trace(Rrel) - 1) / 2)
    i = robot.joint_names.index("leg_left_4_joint")
    assert angle == pytest.approx(meas.q[7 + i] + d.qpos[_qadr(sim, "leg_left_4_joint:drive")], abs=1e-9)


def test_hip_flexibility_deflects_and_is_hidden(robot):
    """The hip spring (in series, above the hip roll joint) deflects under load; the measurement keeps the
    nominal layout."""
    r = preset(robot, {"hip_flexibility": {"joints": ["leg_left_2_joint", "leg_right_2_joint"],
                                           "stiffness": 973.0, "damping": 50.0}})
    sim = Simulator(robot, mode="position", options=SimOptions(realism=r))
    ideal = Simulator(robot, mode="position")
    assert sim.model.nq == ideal.model.nq + 2
    assert sim.measure().q.shape == ideal.measure().q.shape == (robot.nq,)
    # on the hip roll joint's axis, through its origin (in the link above it)
    for side in ("left", "right"):
        a, b = _jid(sim, f"leg_{side}_2_joint"), _jid(sim, f"leg_{side}_2_joint:hip_flex")
        np.testing.assert_allclose(sim.data.xaxis[b], sim.data.xaxis[a], atol=1e-12)
        np.testing.assert_allclose(sim.data.xanchor[b], sim.data.xanchor[a], atol=1e-12)
        assert sim.model.jnt_bodyid[b] == sim.model.body_parentid[sim.model.jnt_bodyid[a]]
    q = robot.q0[7:].copy()
    q[robot.joint_names.index("leg_left_2_joint")] += 0.05  # push the left foot outwards: a roll moment at the hips
    sim.apply(Command(q=q, v=np.zeros(robot.na)))
    sim.step(800)
    left = sim.data.qpos[_qadr(sim, "leg_left_2_joint:hip_flex")]
    assert abs(left) > 1e-3  # N m over 973 N m/rad: a milliradian or more


def test_torque_loop_lags_a_step_by_its_delay():
    dt, delay, bw = 1e-3, 0.003, 50.0
    loop = TorqueLoop(LoopSpec(bandwidth=bw, delay=delay), dt, np.full(2, 100.0))
    out = []
    loop.target[:] = 10.0
    for _ in range(10):
        out.append(loop.next()[0])
    alpha = 1 - math.exp(-2 * math.pi * bw * dt)
    assert out[:3] == [0.0, 0.0, 0.0]  # nothing before the delay
    assert out[3] == pytest.approx(10 * alpha)  # then the first-order response
    assert out[9] == pytest.approx(10 * (1 - (1 - alpha) ** 7))
    assert loop.next()[0] < 10.0
    # the limit holds
    loop.target[:] = 1e6
    for _ in range(20):
        tau = loop.next()
    assert tau[0] == 100.0


def test_torque_loop_kernel_equals_the_numpy_loop():
    """The compiled loop (noise drawn in blocks) delivers the torques of the per-step numpy code bit for bit,
    across a noise block's end and with the limit active."""
    spec = LoopSpec(bandwidth=80.0, delay=0.002, sensor_noise=0.3, seed=4)
    limit = np.array([5.0, 100.0, 100.0])
    loop = TorqueLoop(spec, 1e-3, limit)
    rng, buf, k, out = np.random.default_rng(4), np.zeros((3, 3)), 0, np.zeros(3)
    alpha = 1.0 - math.exp(-2.0 * math.pi * 80.0 * 1e-3)
    targets = np.random.default_rng(9).normal(0.0, 20.0, (TorqueLoop.NOISE_BLOCK + 40, 3))
    for target in targets:
        loop.target[:] = target
        buf[k] = target
        k = (k + 1) % len(buf)
        out += alpha * (buf[k] - out)
        expected = np.clip(out - rng.normal(0.0, 0.3, 3), -limit, limit)
        np.testing.assert_array_equal(loop.next(), expected)
    assert np.abs(expected).max() > 0 and (np.abs(targets[:, 0]) > 5.0).any()


def test_torque_loop_acts_in_the_simulator(robot):
    r = preset(robot, {"torque_loop": {"bandwidth": 100.0, "delay": 0.002, "sensor_noise": 0.0}})
    sim = Simulator(robot, mode="torque", options=SimOptions(realism=r))
    tau = np.zeros(robot.na)
    tau[robot.joint_names.index("leg_left_4_joint")] = 50.0
    sim.apply(Command(tau=tau))
    applied = []
    for _ in range(4):
        sim.step(1)
        applied.append(sim.applied_torque()[robot.joint_names.index("leg_left_4_joint")])
    assert applied[0] == 0.0 and applied[1] == 0.0 and 0.0 < applied[2] < applied[3] < 50.0


def _elbow_moves(robot, extra, torque, steps=200):
    """No gravity: how far the left elbow (coulomb 10 N m over the URDF's 1 N m: break-away 11 N m) moves in
    `steps` physics steps under a constant torque."""
    r = preset(robot, {"actuators": {"arm_left_4_joint": {"coulomb": 10.0}}} | extra)
    sim = Simulator(robot, mode="torque", options=SimOptions(gravity=(0.0, 0.0, 0.0), realism=r))
    tau = np.zeros(robot.na)
    i = robot.joint_names.index("arm_left_4_joint")
    tau[i] = torque
    q0 = sim.measure().q[7 + i]
    sim.apply(Command(tau=tau))
    sim.step(steps)
    return abs(sim.measure().q[7 + i] - q0)


def test_friction_holds_a_joint_below_break_away(robot):
    """The stick-slip friction (the default): below break-away the elbow creeps at torque / stiction_damping
    (8 N m / 1e5 N m s/rad over 0.2 s: 16 urad), ten times less at ten times the damping; above it, it slides, as
    far as under MuJoCo's frictionloss constraint (the former model, `stiction_impedance`), whose creep below
    break-away scales with 1 - d."""
    creep = 8.0 / 1e5 * 0.2
    assert creep * 0.9 < _elbow_moves(robot, {}, 8.0) < creep * 1.1
    assert creep * 0.09 < _elbow_moves(robot, {"stiction_damping": 1e6}, 8.0) < creep * 0.11
    moved = {d: _elbow_moves(robot, {"stiction_impedance": d}, 8.0) for d in (0.999, 0.99)}
    assert moved[0.999] < 1e-5 and moved[0.99] < 1e-4
    assert 5.0 < moved[0.99] / moved[0.999] < 20.0  # (1 - 0.99) / (1 - 0.999) = 10
    slid = _elbow_moves(robot, {}, 13.0)
    assert slid > 1e-2
    assert abs(slid - _elbow_moves(robot, {"stiction_impedance": 0.999}, 13.0)) < 0.05 * slid


def test_friction_stick_slip_in_position_mode_and_faults(robot):
    """Position mode: the servo's feed-forward (qfrc_applied) and the friction kernel's force add up; a joint
    fault on a friction joint keeps its damping through the kernel (locked: it stays where it is)."""
    r = preset(robot, {"actuators": {"arm_left_4_joint": {"coulomb": 10.0}}})
    i = robot.joint_names.index("arm_left_4_joint")
    sim = Simulator(robot, mode="torque", options=SimOptions(gravity=(0.0, 0.0, 0.0), realism=r))
    sim.set_joint_fault("arm_left_4_joint", "locked")
    tau = np.zeros(robot.na)
    tau[i] = 13.0  # above break-away, but the joint is braked
    q0 = sim.measure().q[7 + i]
    sim.apply(Command(tau=tau))
    sim.step(200)
    assert abs(sim.measure().q[7 + i] - q0) < 1e-3
    sim.set_joint_fault("arm_left_4_joint", None)
    assert sim._friction.damping[list(sim._friction.dof).index(sim.bridge.mj_v_idx[i])] < 10.0
    sim = Simulator(robot, mode="position", options=SimOptions(gravity=(0.0, 0.0, 0.0), realism=r))
    q = robot.q0[7:].copy()
    for ff, moves in ((5.0, False), (40.0, True)):
        sim.reset()
        sim.apply(Command(q=q, v=np.zeros(robot.na), tau=np.where(np.arange(robot.na) == i, ff, 0.0)))
        assert sim.data.qfrc_applied[sim.bridge.mj_v_idx[i]] == ff
        sim.step(300)
        err = abs(sim.measure().q[7 + i] - q[i])
        assert (err > 1e-3) == moves, (ff, err)


def test_preset_errors_name_file_and_key(robot):
    with pytest.raises(ConfigError, match=r"p.yaml: key 'actuators.leg_\*.stiffness': must be >= 0"):
        preset(robot, {"actuators": {"leg_*": {"stiffness": -1.0}}}, "p.yaml")
    with pytest.raises(ConfigError, match=r"p.yaml: key 'actuators.arm_left_7_joint.coulomb'.*torque limit"):
        preset(robot, {"actuators": {"arm_left_7_joint": {"coulomb": 10.0}}}, "p.yaml")
    with pytest.raises(ConfigError, match=r"key 'actuators.leg_left_9_joint'.*unknown joint"):
        preset(robot, {"actuators": {"leg_left_9_joint": {"coulomb": 1.0}}}, "p.yaml")
    with pytest.raises(ConfigError, match=r"key 'hip_flexibility.joints\[0\]'.*unknown joint 'hip'"):
        preset(robot, {"hip_flexibility": {"joints": ["hip"], "stiffness": 973.0}}, "p.yaml")
    with pytest.raises(ConfigError, match=r"key 'torque_loop.latency': unknown key"):
        preset(robot, {"torque_loop": {"latency": 0.001}}, "p.yaml")
    with pytest.raises(ConfigError, match=r"p.yaml: key 'stiction_impedance': must be <= 0.9999"):
        preset(robot, {"stiction_impedance": 1.0}, "p.yaml")


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", "stand", "-c", "tsid-torque", "-d", "0.01",
                           *args], capture_output=True, text=True)


@pytest.mark.parametrize("body, needles", [
    ("actuators:\n  'leg_*': {stiffness: -5}\n", ["actuators.leg_*.stiffness", ">= 0"]),
    ("actuators:\n  arm_left_7_joint: {coulomb: 50}\n", ["actuators.arm_left_7_joint.coulomb", "torque limit"]),
    ("hip_flexibility: {joints: [leg_left_7_joint], stiffness: 973}\n", ["hip_flexibility.joints[0]",
                                                                          "leg_left_7_joint"]),
])
def test_cli_bad_preset_is_one_line_exit_2(tmp_path, body, needles, one_line_exit_2):
    f = tmp_path / "mine.yaml"
    f.write_text(body)
    one_line_exit_2(_cli("--realism", str(f), "--out", str(tmp_path / "run")), str(f), *needles)


def test_cli_unknown_preset(tmp_path, one_line_exit_2):
    one_line_exit_2(_cli("--realism", "talos-fake", "--out", str(tmp_path / "run")), "--realism", "talos-fake",
              "talos-real")


def test_run_with_and_without_the_switch(tmp_path):
    """A short run: with the switch, config.json records the preset and the hidden joints are extra columns;
    without it, neither (the nominal columns are the same)."""
    from wbcbench.recorder import read_log
    from wbcbench.runner import run

    off = run("stand", "tsid-torque", duration=0.05, out=tmp_path / "off")
    on = run("stand", "tsid-torque", duration=0.05, out=tmp_path / "on", realism="talos-real")
    c_off = json.loads((tmp_path / "off" / "config.json").read_text())
    c_on = json.loads((tmp_path / "on" / "config.json").read_text())
    assert "realism" not in c_off
    assert c_on["realism"]["name"] == "talos-real" and c_on["sensors"]["name"] == "talos-like"
    log_off, log_on = read_log(tmp_path / "off" / "log.parquet"), read_log(tmp_path / "on" / "log.parquet")
    hidden = [k for k in log_on if k.startswith("hidden_deflection.")]
    assert "hidden_deflection.leg_left_2_joint:hip_flex" in hidden
    assert not [k for k in log_off if k.startswith("hidden_deflection.")]
    extra = {k for k in log_on if k.startswith(("hidden_deflection.", "true_foot_", "base_estimate_error."))}
    assert set(log_on) - extra == set(log_off)  # the nominal columns are kept; hidden ones are extra channels
    assert "landing" in on.summary["metrics"]
    assert not off.summary["fell"] and not on.summary["fell"]
    assert abs(log_on["q.z"][-1] - log_off["q.z"][-1]) < 0.01


def test_landing_errors_on_a_synthetic_log():
    """One planned touch-down at t = 1.0 s; the foot lands 20 ms early, 1 cm ahead and 5 mm to the left."""
    from wbcbench.metrics.landing import landing_errors
    from wbcbench.robots import Side

    t = np.arange(0, 2.0, 1e-3)
    n = len(t)
    log = {"t": t}
    for s, y in ((Side.LEFT, 0.1), (Side.RIGHT, -0.1)):
        log[f"in_contact_ref_{s.value}"] = np.ones(n)
        log[f"contact_{s.value}.fz"] = np.full(n, 400.0)
        log[f"foot_ref_{s.value}.x"] = np.full(n, np.nan)
        log[f"foot_ref_{s.value}.y"] = np.full(n, np.nan)
    swing = (t >= 0.5) & (t < 1.0)
    log["in_contact_ref_left"][swing] = 0.0
    log["contact_left.fz"][(t >= 0.5) & (t < 0.98)] = 0.0
    log["foot_ref_left.x"][swing] = 0.2
    log["foot_ref_left.y"][swing] = 0.1
    feet = {Side.LEFT: np.tile([0.21, 0.105, 0.0], (n, 1)), Side.RIGHT: np.tile([0.0, -0.1, 0.0], (n, 1))}
    out = landing_errors(log, feet)
    (e,) = out["events"]
    assert e["side"] == "left" and e["dt_s"] == pytest.approx(-0.02)
    assert e["dx_m"] == pytest.approx(0.01) and e["dy_m"] == pytest.approx(0.005)
    assert out["summary"]["max_xy_m"] == pytest.approx(math.hypot(0.01, 0.005))


def test_an_empty_preset_changes_no_nominal_column(tmp_path, robot):
    """The switch's machinery with no mechanism in it (an empty preset: the probe, the model-building path) leaves
    every nominal log column bit-identical to the run without the switch."""
    from wbcbench.recorder import read_log
    from wbcbench.runner import run

    empty = preset(robot, {})
    run("stand", "tsid-torque", duration=0.1, out=tmp_path / "off")
    run("stand", "tsid-torque", duration=0.1, out=tmp_path / "empty", realism=empty)
    off, on = read_log(tmp_path / "off" / "log.parquet"), read_log(tmp_path / "empty" / "log.parquet")
    assert set(off) <= set(on)
    for k in off:
        if k != "controller_time_us":
            np.testing.assert_array_equal(on[k], off[k], err_msg=k)


def test_preset_extends_replaces_sections_and_null_removes_one(robot, tmp_path):
    """`extends:` starts from another preset; a section given replaces the base's, a null one removes it."""
    base = load_realism("talos-real", robot)
    act = load_realism("talos-actuation", robot)   # talos-real with ideal sensing
    assert act.sensors == "ideal" and base.sensors == "talos-like"
    assert act.stiffness == base.stiffness and act.hip == base.hip and act.torque_loop == base.torque_loop
    f = tmp_path / "nohip.yaml"
    f.write_text("extends: talos-actuation\nhip_flexibility: null\ntorque_loop: {bandwidth: 50.0}\n")
    mine = load_realism(str(f), robot)
    assert mine.hip is None and mine.torque_loop == LoopSpec(bandwidth=50.0)
    assert mine.stiffness == base.stiffness and mine.sensors == "ideal"
    g = tmp_path / "child.yaml"   # a path relative to the file
    g.write_text("extends: nohip.yaml\nsensors: talos-like\n")
    assert load_realism(str(g), robot).hip is None and load_realism(str(g), robot).sensors == "talos-like"
    h = tmp_path / "constraint.yaml"   # the other friction model replaces the base's stiction_damping
    h.write_text("extends: talos-real\nstiction_impedance: 0.99\n")
    old = load_realism(str(h), robot)
    assert old.stiction_impedance == 0.99 and base.stiction_impedance is None and base.stiction_damping == 1e5
    h.write_text("stiction_impedance: 0.99\nstiction_damping: 1000.0\n")
    with pytest.raises(ConfigError, match="constraint.yaml: key 'stiction_impedance': give either"):
        load_realism(str(h), robot)


@pytest.mark.parametrize("body, needles", [
    ("extends: no-such-preset\n", ["key 'extends'", "no-such-preset", "talos-real"]),
    ("extends: loop.yaml\n", ["key 'extends'", "extends itself"]),
    ("extends: [talos-real]\n", ["key 'extends'", "preset name or file"]),
])
def test_preset_extends_errors(robot, tmp_path, body, needles):
    f = tmp_path / "loop.yaml"
    f.write_text(body)
    with pytest.raises(ConfigError) as e:
        load_realism(str(f), robot)
    for n in [str(f), *needles]:
        assert n in str(e.value), str(e.value)


def test_realism_probe_kernel_equals_numpy(robot):
    """The probe's compiled values are the numpy formulas' (hidden joints' qpos; sole centre p - R offset)."""
    from wbcbench.sim.realism import RealismProbe

    sim = Simulator(robot, mode="torque", options=SimOptions(realism=load_realism("talos-actuation", robot)))
    probe = RealismProbe()
    channels = probe.attach(sim)
    assert len(channels["hidden_deflection"]) == 24
    sim.apply(Command(tau=np.full(robot.na, 3.0)))
    for _ in range(3):
        sim.step(20)
        vals = [np.array(v) for v in probe.values()]
        d = sim.data
        np.testing.assert_array_equal(vals[0], d.qpos[probe._adr])
        for k, g in enumerate(probe._soles):
            expected = d.geom_xpos[g] - d.geom_xmat[g].reshape(3, 3) @ probe._offset
            np.testing.assert_allclose(vals[1 + k], expected, rtol=0, atol=1e-15)
    assert np.abs(vals[0]).max() > 0


def test_friction_kernel_phases_and_bounded_explicit_force():
    """The stick-slip kernel: the damper's explicit force (damping x velocity) never exceeds the break-away torque
    at any velocity; a joint breaks away only when its speed grows beyond coulomb / stick, slides against the
    constant friction and returns to the damper when its velocity changes sign."""
    from wbcbench.sim.friction_kernel import joint_friction_step

    dof = np.array([1], dtype=np.int64)
    fc, own, stick = np.array([2.0]), np.array([0.5]), 1e5
    state, vprev, base = np.zeros(1, np.int64), np.zeros(1), np.array([0.25])
    damping, applied = np.zeros(3), np.zeros(3)

    def step(v):
        joint_friction_step(np.array([0.0, v, 0.0]), dof, fc, own, stick, state, vprev, base, damping, applied)
        return int(state[0])

    for v in (1e-6, -3e-5, 0.3, -2.0, -1e-9):  # (never sliding: the speed does not grow in one direction)
        assert step(v) == 0 and (damping[1] - own[0]) * abs(v) <= fc[0] * (1 + 1e-12) and applied[1] == 0.25
    assert damping[1] == own[0] + stick
    assert step(1e-4) == 0  # (the sign changed since the last step)
    assert step(2e-4) == 1 and damping[1] == own[0] and applied[1] == 0.25 - 2.0  # breaks away
    assert step(0.1) == 1 and step(-1e-3) == 0 and abs((damping[1] - own[0]) * 1e-3 - 2.0) < 1e-12


def test_torque_loop_and_friction_in_one_call_equals_two_calls(robot):
    """The physics step's one compiled call (torque loop and friction) gives the same state, bit for bit, as the
    two calls."""
    r = load_realism("talos-actuation", robot)
    sims = [Simulator(robot, mode="torque", options=SimOptions(realism=r)) for _ in range(2)]
    separate = sims[1]
    separate.step = lambda n=1: [(separate._torque_loop.write(separate._data_views()[6], separate._act_idx),
                                  separate._friction.write(separate.model, separate.data),
                                  mujoco.mj_step(separate.model, separate.data)) for _ in range(n)]
    rng = np.random.default_rng(3)
    for _ in range(5):
        tau = rng.normal(0.0, 5.0, robot.na)
        for sim in sims:
            sim.apply(Command(tau=tau))
            sim.step(20)
    np.testing.assert_array_equal(sims[0].data.qpos, sims[1].data.qpos)
    np.testing.assert_array_equal(sims[0]._friction.state, sims[1]._friction.state)
    assert np.abs(sims[0]._friction.state).sum() > 0  # some joints slid
