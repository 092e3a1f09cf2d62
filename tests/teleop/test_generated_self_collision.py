"""Self-collision keys generated from the collision geometry (wbcbench/robots/collision.py) on the G1 and a
generated profile (GR1 T2): what they name, that the spheres bound the geometry, and a short teleoperation with
self-collision detection on."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest
import yaml

from wbcbench.robots import Side, load_robot
from wbcbench.robots.collision import collision_points, self_collision_keys
from wbcbench.teleop.commands import run_session

ROBOTS = ["g1", "gr1t2"]


def _geometry(robot):
    return pin.buildGeomFromUrdf(robot.model, str(robot.files.urdf), pin.GeometryType.COLLISION,
                                 package_dirs=[str(robot.files.package_root)])


@pytest.fixture(scope="module", params=ROBOTS)
def generated(request):
    if request.param == "gr1t2":
        pytest.importorskip("fourier_robot_descriptions")
    robot = load_robot(request.param)
    geom = _geometry(robot)
    hands = {s.value: f for s, f in robot.profile.hands.items()}
    return robot, geom, self_collision_keys(robot.model, geom, hands, robot.profile.torso_frame, robot.q0)


def _moving_link(model, j):
    return next(f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == j)


def test_collision_check_names_links_with_geometry_and_the_hand_subtree(generated):
    robot, geom, keys = generated
    model = robot.model
    with_geometry = {_moving_link(model, g.parentJoint) for g in geom.geometryObjects}
    for side in Side:
        eff, bodies = keys.collision_check[side.value]
        assert set(eff) | set(bodies) <= with_geometry
        hand_joint = model.frames[model.getFrameId(robot.profile.hands[side])].parentJoint
        arm = set(model.supports[hand_joint]) - set(model.supports[model.frames[model.getFrameId(
            robot.profile.torso_frame)].parentJoint])
        for link in eff:  # the hand's end of its own arm: on the hand's chain or below it, nothing of the body
            j = model.frames[model.getFrameId(link)].parentJoint
            assert j in arm or hand_joint in model.supports[j]
        for link in bodies:  # never on the own arm's chain
            assert model.frames[model.getFrameId(link)].parentJoint not in arm
        other = Side.RIGHT if side is Side.LEFT else Side.LEFT
        assert set(keys.collision_check[other.value][0]) <= set(bodies)  # the other hand
        assert robot.profile.base_frame in bodies
        # the shipped profile carries exactly the generated keys
        assert robot.profile.collision_check[side].effector == tuple(eff)
        assert robot.profile.collision_check[side].bodies == tuple(bodies)


def test_repulsion_spheres_bound_their_links_geometry(generated):
    robot, geom, keys = generated
    model = robot.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, robot.q0)
    points = {}
    for g in geom.geometryObjects:
        points.setdefault(g.parentJoint, []).append(collision_points(g))
    for side in Side:
        frame, offset, radius, spheres = keys.repulsors[side.value]
        assert spheres and radius > 0.01
        by_link = {}
        for _, link, off, r in spheres:
            fid = model.getFrameId(link)
            by_link.setdefault(link, []).append((model.frames[fid].placement.act(np.asarray(off)), r))
        for link, balls in by_link.items():
            j = model.frames[model.getFrameId(link)].parentJoint
            pts = np.vstack(points[j])
            inside = np.zeros(len(pts), bool)
            for c, r in balls:
                inside |= np.linalg.norm(pts - c, axis=1) <= r + 1e-9
            assert inside.all(), link
        # the shipped profile's protected point is the generated one, on the hand
        spec = robot.profile.repulsors[side]
        assert spec.frame == frame and np.allclose(spec.offset, offset, atol=1e-4)
        assert np.linalg.norm(offset) < 0.25


@pytest.mark.parametrize("name", ROBOTS)
def test_teleop_with_self_collision_detection(name, tmp_path):
    """1.5 s of the waving recording with the generated self-collision check counting contacts: no fall, the
    self-collision metrics in the summary, the waving hand tracked."""
    if name == "gr1t2":
        pytest.importorskip("fourier_robot_descriptions")
    res = run_session("waving", robot=name, duration=1.5, out=tmp_path / "run")
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    m = s["metrics"]
    assert isinstance(m["self_collisions"], int) and isinstance(m["self_collision_ticks"], int)
    assert isinstance(m["self_collision_pairs"], dict)
    assert m["hand_position_error_m"]["mean"] < 0.1


def test_a_collision_check_link_the_model_lacks_is_one_line_and_exit_2(tmp_path):
    src = load_robot("g1").profile.file
    data = yaml.safe_load(open(src).read())
    data["collision_check"]["left"]["bodies"] = ["pelvis", "no_such_link"]
    data["loader"] = "g1"
    bad = tmp_path / "g1-bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "teleop", "--mocap", "waving", "--robot", str(bad),
                           "--duration", "0.1", "--out", str(tmp_path / "run")], capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "g1-bad.yaml" in lines[0] and "collision_check.left.bodies" in lines[0] and "no_such_link" in lines[0]
