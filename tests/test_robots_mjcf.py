"""Robots from MJCF: one file builds the pinocchio model (pin.buildModelFromMJCF, its free joint the free flyer) and
the MuJoCo model (MjSpec.from_file); the two agree on kinematics and dynamics to 1e-8; `robot init` generates a
profile from the MJCF's geoms with which the robot stands; bad input is one line, exit 2.

The MJCF is made here, offline, from the G1 URDF of example-robot-data: compiled by MuJoCo (collision geometry
kept, fixed links kept as bodies), a free joint and a reflected rotor inertia added, one joint moved off its body's
origin, the effort limits moved from the joints to actuators, a floor, a sensor and a keyframe added (wbcbench
replaces the actuators, sensors, keys and world geoms by its own), saved with
MjSpec.to_xml (meshes by absolute path): a model the code reads only as MJCF."""

import json
import re
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import yaml

from wbcbench.cli import main
from wbcbench.robots import Side, load_robot
from wbcbench.scene import Terrain
from wbcbench.sim.model import SimOptions, ft_site_name, sole_geom_name
from wbcbench.sim.simulator import Simulator

#: the joint moved off its body's origin (perpendicular to its x axis): pinocchio's joint frame is then not the
#: MuJoCo body's frame, and the F/T site (at the joint) sits away from the body origin
OFFSET_JOINT, OFFSET = "left_ankle_roll_joint", (0.0, 0.004, 0.006)


def write_g1_mjcf(out: Path) -> Path:
    urdf_robot = load_robot("g1")
    files = urdf_robot.files
    txt = files.path.read_text()
    txt = re.sub(r"<visual\b.*?</visual>", "", txt, flags=re.S)
    txt = txt.replace("package://", str(files.package_root) + "/")
    txt = re.sub(r'(<mesh\b[^>]*?\bfilename=")(?![/\\])([^"]+)"',
                 lambda m: f'{m.group(1)}{(files.path.parent / m.group(2)).resolve()}"', txt)
    txt = re.sub(r"(<robot\b[^>]*>)", r'\1<mujoco><compiler discardvisual="true" fusestatic="false" '
                 r'strippath="false" balanceinertia="false" autolimits="true"/></mujoco>', txt, count=1)
    spec = mujoco.MjSpec.from_string(txt)
    spec.worldbody.first_body().add_freejoint(name="floating_base")
    for j in spec.joints:
        if j.type == mujoco.mjtJoint.mjJNT_HINGE:
            j.armature = 0.01
    spec.joint(OFFSET_JOINT).pos = list(OFFSET)
    # what an MJCF robot file carries and wbcbench replaces: a floor, actuators (named as the joints), a sensor, a key
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05])
    # the effort limits on the actuators, as Menagerie models give them: a force range, or a motor's control range
    # times its gear (every other joint)
    for k, j in enumerate(spec.joints[1:]):
        tau = float(j.actfrcrange[1])
        j.actfrcrange = [0.0, 0.0]
        j.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
        a = spec.add_actuator(name=j.name, target=j.name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        if k % 2:
            a.forcelimited, a.forcerange = mujoco.mjtLimited.mjLIMITED_TRUE, [-tau, tau]
        else:
            a.ctrllimited, a.ctrlrange = mujoco.mjtLimited.mjLIMITED_TRUE, [-tau / 4, tau / 4]
            a.gear = [4, 0, 0, 0, 0, 0]
    spec.add_sensor(name="gyro", type=mujoco.mjtSensor.mjSENS_JOINTPOS, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                    objname="left_knee_joint")
    spec.compile()
    spec.add_key(name="home", qpos=list(np.r_[0, 0, 0.8, 1, 0, 0, 0, np.zeros(len(spec.joints) - 1)]))
    spec.compile()
    out.write_text(spec.to_xml())
    return out


@pytest.fixture(scope="module")
def g1_mjcf(tmp_path_factory) -> Path:
    return write_g1_mjcf(tmp_path_factory.mktemp("mjcf") / "g1_from_mjcf.xml")


@pytest.fixture(scope="module")
def profile(g1_mjcf) -> Path:
    out = g1_mjcf.parent / "g1m.yaml"
    assert main(["robot", "init", str(g1_mjcf), "--out", str(out), "--name", "g1m"]) == 0
    return out


@pytest.fixture(scope="module")
def robot(profile):
    return load_robot(profile)


def test_pinocchio_reads_the_mjcf(g1_mjcf, robot):
    data = yaml.safe_load(Path(robot.profile.file).read_text())
    assert data["loader"] == str(g1_mjcf) and robot.files.is_mjcf
    assert robot.model.names[1] == "floating_base" and robot.model.joints[1].shortname() == "JointModelFreeFlyer"
    mj = mujoco.MjModel.from_xml_path(str(g1_mjcf))
    hinges = [mj.joint(j).name for j in range(mj.njnt) if mj.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    assert robot.joint_names == hinges  # the file's (depth-first) order
    assert np.all(robot.model.armature[6:] == 0.01) and "armature" not in data["limits"]  # read from the file
    assert np.array_equal(robot.effort_limit, load_robot("g1").effort_limit)  # from the file's actuators
    assert "actuatorfrcrange" not in g1_mjcf.read_text()
    assert robot.mass == pytest.approx(float(mj.body_mass.sum()), abs=1e-12)
    assert data["feet"]["left"]["parent_frame"] == "left_ankle_roll_link"
    with pytest.raises(Exception, match="MJCF"):
        robot.files.urdf  # noqa: B018  (code that reads URDF only is told it is not one)


def _velocity_map(sim, q) -> np.ndarray:
    b = sim.bridge
    T = np.zeros((sim.model.nv, len(q) - 1))
    T[b.root_vadr:b.root_vadr + 3, 0:3] = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    T[b.root_vadr + 3:b.root_vadr + 6, 3:6] = np.eye(3)
    T[b.mj_v_idx, b.pin_v_idx] = 1.0
    return T


def test_bridge_kinematics_and_dynamics_agree(robot):
    """Every body frame, the soles, the F/T and IMU sites, the CoM, the mass matrix and gravity to 1e-8; pinocchio's
    RNEA on MuJoCo's accelerations gives MuJoCo's joint forces."""
    sim = Simulator(robot, Terrain(floor=False), "torque")
    m, d = robot.model, robot.model.createData()
    rng = np.random.default_rng(0)
    lo, hi = robot.position_limits
    bodies = [f.name for f in m.frames if f.type == pin.FrameType.BODY]
    assert len(bodies) == sim.model.nbody - 1  # fixed links are bodies in both
    for _ in range(3):
        q = robot.q0.copy()
        q[7:] = rng.uniform(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo))
        q[:3] = rng.normal(size=3) + [0, 0, 3.0]
        q[3:7] = pin.Quaternion(pin.exp3(rng.normal(size=3))).coeffs()
        v = rng.normal(size=robot.nv)
        sim.reset(q, v)
        mujoco.mj_forward(sim.model, sim.data)
        pin.framesForwardKinematics(m, d, q)
        for name in bodies:
            bid = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, name)
            M = d.oMf[m.getFrameId(name, pin.FrameType.BODY)]
            assert np.allclose(sim.data.xpos[bid], M.translation, atol=1e-8), name
            assert np.allclose(sim.data.xmat[bid].reshape(3, 3), M.rotation, atol=1e-8), name
        sole = robot.profile.sole
        for s in Side:
            foot = d.oMf[robot.sole_frame_id(s)]
            gid = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_GEOM, sole_geom_name(s))
            assert np.allclose(sim.data.geom_xpos[gid], foot.act(np.array([*sole.center, sole.thickness / 2])),
                               atol=1e-8)
            assert np.allclose(sim.data.geom_xmat[gid].reshape(3, 3), foot.rotation, atol=1e-8)
            ft = d.oMf[m.getFrameId(robot.profile.feet[s].ft_sensor_frame)]
            sid = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_SITE, ft_site_name(s))
            assert np.allclose(sim.data.site_xpos[sid], ft.translation, atol=1e-8)
            assert np.allclose(sim.data.site_xmat[sid].reshape(3, 3), ft.rotation, atol=1e-8)
        imu = d.oMf[m.getFrameId(robot.profile.imu_frame)]
        sid = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_SITE, "imu")
        assert np.allclose(sim.data.site_xpos[sid], imu.translation, atol=1e-8)
        base = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, robot.profile.base_frame)
        assert np.allclose(sim.data.subtree_com[base], pin.centerOfMass(m, d, q), atol=1e-8)
        T = _velocity_map(sim, q)
        M_mj = np.zeros((sim.model.nv, sim.model.nv))
        mujoco.mj_fullM(sim.model, sim.data, M_mj)
        M_pin = pin.crba(m, d, q)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        assert np.allclose(T.T @ M_mj @ T, M_pin, atol=1e-8)
        sim.reset(q, np.zeros(robot.nv))
        mujoco.mj_forward(sim.model, sim.data)
        assert np.allclose(T.T @ sim.data.qfrc_bias, pin.computeGeneralizedGravity(m, d, q), atol=1e-8)


def test_the_offset_joint_is_off_its_body_origin(robot):
    """The placement path the test above covers: the moved joint's body frame is not its joint frame."""
    m = robot.model
    jid = m.getJointId(OFFSET_JOINT)
    body = next(f for f in m.frames if f.type == pin.FrameType.BODY and f.parentJoint == jid)
    assert np.allclose(body.placement.translation, -np.asarray(OFFSET), atol=1e-12)


def test_the_generated_profile_stands(profile, tmp_path):
    out = tmp_path / "run"
    assert main(["run", "stand", "-c", "tsid-torque", "--robot", str(profile), "-d", "2", "--quiet",
                 "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert not s["fell"] and s["sim_time_s"] == pytest.approx(2.0, abs=0.01)
    assert abs(s["metrics"]["base_height_change_m"]) < 0.005


def test_self_collision_and_realism_build_on_mjcf(robot):
    """The generated collision_check selects the MJCF's own colliding geoms; a drive's hidden spring deflects by
    torque / stiffness, as on a URDF robot (tests/sim/test_realism.py)."""
    from wbcbench.config import Section
    from wbcbench.sim.model import build_self_collision_model
    from wbcbench.sim.realism import parse_realism
    from wbcbench.types import Command

    mj = build_self_collision_model(robot)
    names = [mj.geom(g).name for g in range(mj.ngeom)]
    eff = robot.profile.collision_check[Side.LEFT].effector
    assert any(n.startswith(f"selfcol:{eff[0]}:") for n in names)
    K = 20000.0
    r = parse_realism(Section({"actuators": {"*knee*": {"stiffness": K, "damping": 100.0}}}, "p.yaml"), robot)
    sim = Simulator(robot, mode="position", options=SimOptions(realism=r))
    sim.apply(Command(q=robot.q0[7:].copy(), v=np.zeros(robot.na)))
    sim.step(1500)
    assert not sim.fall_status().fell
    i = robot.joint_names.index("left_knee_joint")
    jid = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_JOINT, "left_knee_joint:drive")
    deflection = sim.data.qpos[sim.model.jnt_qposadr[jid]]
    tau = sim.applied_torque()[i]
    assert abs(tau) > 1.0 and -deflection == pytest.approx(tau / K, rel=0.02)  # the link lags the motor


# ---------------------------------------------------------------- bad input: one line, exit 2

@pytest.fixture
def one_line_exit_2(capsys):
    """`main(argv)` fails as bad input does: exit 2, one line on stderr naming each of `needles` (in-process: the
    conftest fixture of the same name checks a subprocess)."""
    def check(argv, *needles):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "Traceback" not in err, err
        for n in needles:
            assert n in err, err
    return check


def _with_loader(profile, tmp_path, loader):
    """A copy of the generated profile (tmp_path/bad.yaml) whose `loader` is `loader`."""
    bad = tmp_path / "bad.yaml"
    bad.write_text(profile.read_text().replace(f"loader: {yaml.safe_load(profile.read_text())['loader']}",
                                               f"loader: {loader}"))
    return bad


def test_missing_mjcf_file(tmp_path, profile, one_line_exit_2):
    one_line_exit_2(["robot", "init", str(tmp_path / "nope.xml"), "--out", str(tmp_path / "x.yaml")],
                    "nope.xml", "does not exist", "SOURCE")
    bad = _with_loader(profile, tmp_path, "gone.xml")
    one_line_exit_2(["run", "stand", "-c", "tsid-torque", "--robot", str(bad), "-d", "0.1"],
                    "bad.yaml", "'loader'", "gone.xml", "does not exist")


def test_an_mjcf_without_a_free_joint(tmp_path, profile, one_line_exit_2):
    arm = tmp_path / "arm.xml"
    arm.write_text('<mujoco><worldbody><body name="b"><joint name="j" type="hinge"/><geom size="0.1"/></body>'
                   '</worldbody></mujoco>')
    one_line_exit_2(["robot", "init", str(arm), "--out", str(tmp_path / "x.yaml")], "arm.xml", "no free joint")
    bad = _with_loader(profile, tmp_path, arm)
    one_line_exit_2(["run", "stand", "-c", "tsid-torque", "--robot", str(bad), "-d", "0.1"],
                    "bad.yaml", "'loader'", "arm.xml", "no free joint")


def test_an_mjcf_without_feet(tmp_path, one_line_exit_2):
    stick = tmp_path / "stick.xml"
    stick.write_text('<mujoco><worldbody><body name="base" pos="0 0 1"><freejoint/><geom type="box" '
                     'size="0.1 0.1 0.1"/><body name="arm" pos="0 0 -0.2"><joint name="j" axis="0 1 0" range="-1 1" '
                     'actuatorfrcrange="-10 10"/><geom type="capsule" size="0.03 0.1"/></body></body></worldbody>'
                     '</mujoco>')
    one_line_exit_2(["robot", "init", str(stick), "--out", str(tmp_path / "x.yaml")], "stick.xml", "'feet'")


def test_a_body_whose_mass_mujoco_infers_from_its_mesh(g1_mjcf, profile, tmp_path, one_line_exit_2):
    """Without its <inertial> the knee's mass comes from its mesh in MuJoCo and not in pinocchio: refused."""
    text = re.sub(r'(<body name="left_knee_link"[^>]*>\s*)<inertial[^>]*/>', r"\1", g1_mjcf.read_text())
    assert "left_knee_link" in text and text != g1_mjcf.read_text()
    (tmp_path / "massless_knee.xml").write_text(text)
    bad = _with_loader(profile, tmp_path, "massless_knee.xml")
    one_line_exit_2(["run", "stand", "-c", "tsid-torque", "--robot", str(bad), "-d", "0.1"],
                    "bad.yaml", "'loader'", "massless_knee.xml", "<inertial>")


def test_a_profile_naming_a_frame_the_mjcf_lacks(tmp_path, profile, one_line_exit_2):
    data = yaml.safe_load(profile.read_text())
    data["imu_frame"] = "no_such_imu"
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    one_line_exit_2(["run", "stand", "-c", "tsid-torque", "--robot", str(bad), "-d", "0.1"],
                    "bad.yaml", "imu_frame", "no_such_imu")


def test_dart_refuses_an_mjcf_robot(profile, one_line_exit_2):
    pytest.importorskip("dartpy")
    one_line_exit_2(["run", "stand", "-c", "tsid-torque", "--robot", str(profile), "-d", "0.1", "--engine", "dart"],
                    "g1m.yaml", "--engine", "MJCF")


def test_a_menagerie_model_without_the_package_says_so(tmp_path, one_line_exit_2):
    try:
        import mujoco_menagerie  # noqa: F401
    except ImportError:
        pass
    else:
        pytest.skip("mujoco-menagerie is installed: a Menagerie source would download (never in tests)")
    one_line_exit_2(["robot", "init", "menagerie:unitree_g1", "--out", str(tmp_path / "x.yaml")],
                    "menagerie:unitree_g1", "pip install mujoco-menagerie", "SOURCE")


def test_a_menagerie_source_from_a_local_checkout(g1_mjcf, tmp_path, monkeypatch, one_line_exit_2):
    """`menagerie:unitree_g1` through mujoco-menagerie, offline: MENAGERIE_ROOT names a checkout (here holding the
    test MJCF as unitree_g1/g1.xml, the G1's default model file), so nothing is downloaded."""
    pytest.importorskip("mujoco_menagerie")
    (tmp_path / "unitree_g1").mkdir()
    (tmp_path / "unitree_g1" / "g1.xml").write_text(g1_mjcf.read_text())
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path))
    out = tmp_path / "menagerie_g1.yaml"
    assert main(["robot", "init", "menagerie:unitree_g1", "--out", str(out)]) == 0
    assert yaml.safe_load(out.read_text())["loader"] == "menagerie:unitree_g1"
    robot = load_robot(out)
    assert robot.files.path == (tmp_path / "unitree_g1" / "g1.xml").resolve() and robot.files.is_mjcf
    Simulator(robot, Terrain(floor=False), "torque")  # the MuJoCo model builds and its mass agrees
    one_line_exit_2(["robot", "init", "menagerie:unitree_g9", "--out", str(tmp_path / "x.yaml")],
                    "unknown Menagerie robot 'unitree_g9'", "unitree_g1", "SOURCE")
    one_line_exit_2(["robot", "init", "menagerie:unitree_g1/nope", "--out", str(tmp_path / "x.yaml")],
                    "nope", "g1_with_hands", "SOURCE")
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path / "empty"))  # a checkout without the robot: one line
    one_line_exit_2(["robot", "init", "menagerie:unitree_g1", "--out", str(tmp_path / "x.yaml")],
                    "menagerie:unitree_g1", "MENAGERIE_ROOT", "SOURCE")
