"""`wbcbench robot init`: a profile generated from a humanoid's model that no shipped profile describes (the
Fourier GR1 T1 of fourier-robot-descriptions) loads, and the robot stands with tsid-torque without editing."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from wbcbench.cli import main
from wbcbench.robots import Side, load_robot
from wbcbench.robots.generate import generate_profile

pytest.importorskip("fourier_robot_descriptions")


@pytest.fixture(scope="module")
def gr1t1_profile(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("init") / "gr1t1.yaml"
    assert main(["robot", "init", "gr1t1", "--out", str(out)]) == 0
    return out


def test_init_finds_the_robot(gr1t1_profile):
    data = yaml.safe_load(gr1t1_profile.read_text())
    assert data["loader"] == "fourier:gr1t1"
    assert data["feet"]["left"]["parent_frame"] == "left_foot_roll_link"
    assert data["feet"]["right"]["ft_sensor_frame"] == "right_ankle_roll_joint"
    assert data["imu_frame"] == "IMU_joint" and data["torso_frame"] == "torso_link"
    assert 0.15 < data["sole"]["length"] < 0.3 and 0.05 < data["sole"]["width"] < 0.12
    robot = load_robot(gr1t1_profile)
    # the posture: knees bent 0.6 rad, soles flat and at the same height, the CoM over the middle of the feet
    d = robot.model.createData()
    import pinocchio as pin

    com = pin.centerOfMass(robot.model, d, robot.q0)
    pin.framesForwardKinematics(robot.model, d, robot.q0)
    soles = [d.oMf[robot.sole_frame_id(s)] for s in Side]
    for M in soles:
        assert np.linalg.norm(pin.log3(M.rotation)) < 1e-3
        assert abs(M.translation[2]) < 1e-3
    assert np.allclose(com[:2], (soles[0].translation[:2] + soles[1].translation[:2]) / 2, atol=2e-3)
    knee = robot.joint_names.index("left_knee_pitch_joint")
    assert robot.q0[7 + knee] == pytest.approx(0.6)


def test_generated_profile_stands_5s_with_tsid_torque(gr1t1_profile):
    from wbcbench.runner import run

    res = run("stand", "tsid-torque", robot=load_robot(gr1t1_profile), duration=5.0)
    s = res.summary
    assert not s["fell"] and s["sim_time_s"] == pytest.approx(5.0, abs=0.01)
    assert abs(s["metrics"]["base_height_change_m"]) < 0.01


def test_missing_model_and_no_feet_are_one_line_exit_2(tmp_path, capsys):
    assert main(["robot", "init", str(tmp_path / "nope.urdf"), "--out", str(tmp_path / "x.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "nope.urdf" in err and "does not exist" in err
    # a URDF without collision geometry: no feet to find
    urdf = tmp_path / "stick.urdf"
    urdf.write_text('<robot name="stick"><link name="base"><inertial><mass value="1"/><inertia ixx="0.1" '
                    'iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
                    '<joint name="j" type="revolute"><parent link="base"/><child link="leg"/><axis xyz="0 1 0"/>'
                    '<limit lower="-1" upper="1" effort="10" velocity="1"/></joint><link name="leg"><inertial>'
                    '<mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/>'
                    '</inertial></link></robot>')
    assert main(["robot", "init", str(urdf), "--out", str(tmp_path / "x.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "stick.urdf" in err and "'feet'" in err


def test_profile_naming_a_missing_frame_is_one_line_exit_2(gr1t1_profile, tmp_path, capsys):
    data = yaml.safe_load(gr1t1_profile.read_text())
    data["imu_frame"] = "no_such_imu"
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    assert main(["run", "stand", "-c", "tsid-torque", "--robot", str(bad), "-d", "0.1"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "bad.yaml" in err and "imu_frame" in err and "no_such_imu" in err
    data["imu_frame"] = "IMU_joint"
    data["loader"] = str(tmp_path / "missing.urdf")
    bad.write_text(yaml.safe_dump(data))
    assert main(["run", "stand", "-c", "tsid-torque", "--robot", str(bad), "-d", "0.1"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "bad.yaml" in err and "loader" in err and "missing.urdf" in err


def test_generator_on_a_second_source():
    """Romeo (example-robot-data): massless finger links and hand joints without limits are filled in."""
    gen = generate_profile("romeo")
    data = yaml.safe_load(gen.text)
    assert data["limits"]["min_body_mass"] > 0
    assert data["feet"]["left"]["ft_sensor_frame"] != data["feet"]["right"]["ft_sensor_frame"]


def test_an_upper_body_has_no_feet(tmp_path, capsys):
    """Alexander's upper body (example-robot-data alex_nub_hands): its grippers are the lowest geometry, far above
    where legs would end; no feet, one line, exit 2."""
    assert main(["robot", "init", "alex_nub_hands", "--out", str(tmp_path / "x.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "alex_nub_hands.urdf" in err and "'feet'" in err
