"""Every shipped robot: the profile loads, `wbcbench list` shows it, pinocchio and MuJoCo agree on its kinematics
and dynamics (CoM, mass matrix, gravity) to 1e-8, and it stands with tsid-torque."""

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from wbcbench.robots import Side, load_robot
from wbcbench.robots.profile import builtin_robots
from wbcbench.scene import Terrain
from wbcbench.sim.model import sole_geom_name
from wbcbench.sim.simulator import Simulator

ROBOTS = builtin_robots()
GENERATED = ["alexander", "gr1t2", "gr2t2", "gr2t2d", "gr2t2v2", "gr3", "qinglong", "romeo"]  # profiles written by `wbcbench robot init`


def test_the_shipped_robots_are_listed(capsys):
    from wbcbench.cli import main

    assert set(GENERATED) <= set(ROBOTS) and len(ROBOTS) >= 10
    assert main(["list"]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("robots:"))
    assert all(r in line for r in ROBOTS)


def _velocity_map(sim, q) -> np.ndarray:
    """T with v_mujoco = T v_pinocchio (free joint: world linear, local angular; pinocchio: local both)."""
    b = sim.bridge
    nv = sim.model.nv
    T = np.zeros((nv, len(q) - 1))
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    T[b.root_vadr:b.root_vadr + 3, 0:3] = R
    T[b.root_vadr + 3:b.root_vadr + 6, 3:6] = np.eye(3)
    T[b.mj_v_idx, b.pin_v_idx] = 1.0
    return T


@pytest.mark.parametrize("name", ROBOTS)
def test_bridge_kinematics_mass_matrix_and_gravity_agree(name):
    robot = load_robot(name)
    sim = Simulator(robot, Terrain(floor=False), "torque")
    m, d = robot.model, robot.model.createData()
    base_body = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, robot.profile.base_frame)
    rng = np.random.default_rng(0)
    lo, hi = robot.position_limits
    for _ in range(3):
        q = robot.q0.copy()
        q[7:] = rng.uniform(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo))
        q[:3] = rng.normal(size=3) + [0, 0, 3.0]
        q[3:7] = pin.Quaternion(pin.exp3(rng.normal(size=3))).coeffs()
        sim.reset(q, np.zeros(robot.nv))
        mujoco.mj_forward(sim.model, sim.data)
        pin.centerOfMass(m, d, q)
        assert np.allclose(sim.data.subtree_com[base_body], d.com[0], atol=1e-8)
        pin.framesForwardKinematics(m, d, q)
        for s in Side:
            gid = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_GEOM, sole_geom_name(s))
            foot = d.oMf[robot.sole_frame_id(s)]
            assert np.allclose(sim.data.geom_xmat[gid].reshape(3, 3), foot.rotation, atol=1e-8)
        T = _velocity_map(sim, q)
        M_mj = np.zeros((sim.model.nv, sim.model.nv))
        mujoco.mj_fullM(sim.model, sim.data, M_mj)  # MuJoCo 4 signature
        M_pin = pin.crba(m, d, q)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        assert np.allclose(T.T @ M_mj @ T, M_pin, atol=1e-8)
        g_pin = pin.computeGeneralizedGravity(m, d, q)
        assert np.allclose(T.T @ sim.data.qfrc_bias, g_pin, atol=1e-8)


@pytest.mark.parametrize("name", GENERATED)
def test_generated_profiles_stand_with_tsid_torque(name):
    from wbcbench.runner import run

    s = run("stand", "tsid-torque", robot=load_robot(name), duration=3.0).summary
    assert not s["fell"] and s["sim_time_s"] == pytest.approx(3.0, abs=0.01)
    assert abs(s["metrics"]["base_height_change_m"]) < 0.01


def test_a_generated_profile_walks_with_tsid_position(tmp_path):
    """The generic tsid-position set (DCM stabilizer, relaxed model sole, base feedback, the QP torques fed forward to
    the servos but the ankles') walks the GR1 T2's generated profile through the quick 20 cm walk: no fall, the whole
    scenario, the base within 2 cm of its planned final position (measured 0.25 cm; without the feed-forward it fell
    at 5.3 s)."""
    from wbcbench.runner import run

    s = run("walk-20cm-quick", "tsid-position", robot=load_robot("gr1t2"), out=tmp_path / "run").summary
    assert not s["fell"] and s["sim_time_s"] == pytest.approx(s["duration_s"], abs=0.01)
    assert s["metrics"]["final_position_error_m"] < 0.02
    assert s["metrics"]["distance_m"] > 0.35
