"""MuJoCo and pinocchio agree on kinematics and dynamics through the state bridge, on random states."""

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from wbcbench.robots import Side
from wbcbench.sim.model import ft_site_name, sole_geom_name
from wbcbench.sim.simulator import Simulator
from wbcbench.scene import Terrain


def random_state(robot, rng):
    lo, hi = robot.position_limits
    q = robot.q0.copy()
    q[7:] = rng.uniform(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo))
    q[:3] = rng.normal(size=3) + [0, 0, 3.0]  # in the air: no contact
    quat = pin.Quaternion(pin.exp3(rng.normal(size=3)))
    q[3:7] = quat.coeffs()
    v = rng.normal(size=robot.nv)
    return q, v


@pytest.fixture(params=["talos", "g1"])
def robot(request, talos, g1):
    return {"talos": talos, "g1": g1}[request.param]


def test_round_trip_is_exact(robot):
    sim = Simulator(robot, Terrain(floor=False), "torque")
    rng = np.random.default_rng(0)
    for _ in range(5):
        q, v = random_state(robot, rng)
        sim.reset(q, v)
        assert np.allclose(sim.true_q(), q, atol=1e-14)
        assert np.allclose(sim.true_v(), v, atol=1e-13)


def test_integration_agrees(robot):
    """mj_integratePos and pin.integrate agree: the velocity conventions are consistent."""
    sim = Simulator(robot, Terrain(floor=False), "torque")
    rng = np.random.default_rng(1)
    q, v = random_state(robot, rng)
    sim.reset(q, v)
    qpos = sim.data.qpos.copy()
    mujoco.mj_integratePos(sim.model, qpos, sim.data.qvel, 1e-3)
    q_next = pin.integrate(robot.model, q, v * 1e-3)
    assert np.allclose(sim.bridge.q_from_mj(qpos), q_next, atol=1e-12)


def test_kinematics_agree(robot):
    sim = Simulator(robot, Terrain(floor=False), "torque")
    m, d = robot.model, robot.model.createData()
    base_body = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, robot.profile.base_frame)
    rng = np.random.default_rng(2)
    for _ in range(5):
        q, v = random_state(robot, rng)
        sim.reset(q, v)
        mujoco.mj_subtreeVel(sim.model, sim.data)
        pin.centerOfMass(m, d, q, v)
        assert np.allclose(sim.data.subtree_com[base_body], d.com[0], atol=1e-9)
        assert np.allclose(sim.data.subtree_linvel[base_body], d.vcom[0], atol=1e-9)
        pin.framesForwardKinematics(m, d, q)
        sole = robot.profile.sole
        for s in Side:
            foot = d.oMf[robot.sole_frame_id(s)]
            gid = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_GEOM, sole_geom_name(s))
            centre = foot.act(np.array([*sole.center, sole.thickness / 2]))
            assert np.allclose(sim.data.geom_xpos[gid], centre, atol=1e-9)
            assert np.allclose(sim.data.geom_xmat[gid].reshape(3, 3), foot.rotation, atol=1e-9)
            ft = d.oMf[m.getFrameId(robot.profile.feet[s].ft_sensor_frame)]
            sid = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_SITE, ft_site_name(s))
            assert np.allclose(sim.data.site_xpos[sid], ft.translation, atol=1e-9)
            assert np.allclose(sim.data.site_xmat[sid].reshape(3, 3), ft.rotation, atol=1e-9)


def test_dynamics_and_ankle_wrenches_agree(robot):
    """Same masses, armature and frames: pinocchio's RNEA with MuJoCo's accelerations reproduces MuJoCo's
    joint forces, and the ankle F/T sensor equals the spatial force the leg transmits to the foot through the joint."""
    sim = Simulator(robot, Terrain(floor=False), "torque")
    m, d = robot.model, robot.model.createData()
    b = sim.bridge
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, v = random_state(robot, rng)
        sim.reset(q, v)
        tau = rng.normal(size=robot.na) * 5
        sim.data.ctrl[b.actuator_idx] = tau
        mujoco.mj_forward(sim.model, sim.data)
        qacc = sim.data.qacc
        R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        a = np.empty(robot.nv)
        a[0:3] = R.T @ qacc[b.root_vadr:b.root_vadr + 3] - np.cross(v[3:6], v[0:3])
        a[3:6] = qacc[b.root_vadr + 3:b.root_vadr + 6]
        a[b.pin_v_idx] = qacc[b.mj_v_idx]
        tau_pin = pin.rnea(m, d, q, v, a)
        # base: no actuation; joints: motor torque + damping + dry friction (a MuJoCo constraint force)
        passive = sim.data.qfrc_passive[b.mj_v_idx] + sim.data.qfrc_constraint[b.mj_v_idx]
        assert np.allclose(tau_pin[:6], 0.0, atol=1e-8)
        applied = sim.data.qfrc_actuator[b.mj_v_idx]  # tau clamped to the effort limits
        assert np.allclose(applied, np.clip(tau, -robot.effort_limit, robot.effort_limit), atol=1e-12)
        assert np.allclose(tau_pin[6:], applied + passive, atol=1e-8)
        meas = sim.measure()
        for s in Side:
            fid = m.getFrameId(robot.profile.feet[s].ft_sensor_frame)
            frame = m.frames[fid]
            f_joint = d.f[frame.parentJoint]  # parent -> child, in the joint frame
            f_site = frame.placement.actInv(f_joint)
            assert np.allclose(meas.ft_force[s], f_site.linear, atol=1e-8)
            assert np.allclose(meas.ft_torque[s], f_site.angular, atol=1e-8)
