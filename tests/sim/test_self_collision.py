"""Self-collision checking in MuJoCo: the gripper and body collision meshes of the profile, counted per tick."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import yaml

from wbcbench.errors import ConfigError
from wbcbench.robots import Side, load_robot
from wbcbench.sim.model import SimOptions
from wbcbench.sim.self_collision import SelfCollisionMonitor, SelfCollisionProbe
from wbcbench.sim.simulator import Simulator
from wbcbench.types import Command

# A left-arm and torso configuration that puts the left gripper inside the left hip/thigh (found by IK on the
# arms-down hand target of the `reach_forward` recording, joint limits respected).
ARM_IN_HIP = {"arm_left_1_joint": 0.33, "arm_left_2_joint": 0.0, "arm_left_3_joint": -0.58, "arm_left_4_joint": -0.65,
              "arm_left_5_joint": 0.05, "arm_left_6_joint": -0.59, "arm_left_7_joint": 0.05, "torso_1_joint": 0.51,
              "torso_2_joint": 0.24}


def _q_in_hip(robot):
    q = robot.q0.copy()
    m = robot.model
    for name, val in ARM_IN_HIP.items():
        q[m.idx_qs[m.getJointId(name)]] = val
    return q


def _hold(sim, robot, n=30):
    for _ in range(n):
        sim.apply(Command(q=robot.q0[7:].copy(), v=np.zeros(robot.na)))
        sim.step(1)


def test_detect_leaves_the_simulated_model_unchanged(talos):
    off = Simulator(talos, mode="spd")
    det = Simulator(talos, mode="spd", options=SimOptions(self_collision="detect"))
    assert det.model.ngeom == off.model.ngeom and det.model.nbody == off.model.nbody
    _hold(off, talos)
    _hold(det, talos)
    np.testing.assert_array_equal(off.data.qpos, det.data.qpos)


def test_each_collision_geom_has_its_own_urdf_mesh(talos):
    """Two URDF meshes of the same file name in different folders (TALOS: gripper/ and torso/
    base_link_collision.STL) stay two meshes: MuJoCo 3's URDF import alone gave the pelvis's to the grippers."""
    from wbcbench.sim.model import _collision_mesh_files, _urdf_for_mujoco, build_self_collision_model, \
        self_collision_geom_name

    m = build_self_collision_model(talos)
    keep = frozenset(link for c in talos.profile.collision_check.values() for link in (*c.effector, *c.bodies))
    files = _collision_mesh_files(_urdf_for_mujoco(talos, keep))
    mesh_of_file: dict[str, set[int]] = {}
    for link in keep:
        for k, item in enumerate(files[link]):
            g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, self_collision_geom_name(link, k))
            if item is not None:
                mesh_of_file.setdefault(item[0], set()).add(int(m.geom_dataid[g]))
    gripper = [f for f in mesh_of_file if f.endswith("gripper/base_link_collision.STL")]
    pelvis = [f for f in mesh_of_file if f.endswith("torso/base_link_collision.STL")]
    assert gripper and pelvis  # the case this test is about is in the check
    meshes = list(mesh_of_file.values())
    assert len(set().union(*meshes)) == sum(len(a) for a in meshes)  # no mesh serves two files


def test_monitor_counts_gripper_in_hip_and_nothing_in_half_sitting(talos):
    sim = Simulator(talos, mode="spd", options=SimOptions(self_collision="detect"))
    mon = SelfCollisionMonitor(sim)
    assert mon.update() == set()
    sim.reset(_q_in_hip(talos))
    hits = mon.update()
    assert hits and all(side is Side.LEFT for side, _ in hits)
    assert {link for _, link in hits} & {"leg_left_1_link", "leg_left_2_link", "leg_left_3_link", "base_link"}


def test_the_copy_is_set_to_the_simulated_configuration(talos):
    """The kinematic copy takes the simulator's qpos directly: the same numbers as through pinocchio's q."""
    sim = Simulator(talos, mode="spd", options=SimOptions(self_collision="detect"))
    mon = SelfCollisionMonitor(sim)
    q = _q_in_hip(talos)
    q[:3] += (0.1, -0.2, 0.05)
    quat = np.array([0.1, -0.2, 0.3, 0.9])
    q[3:7] = quat / np.linalg.norm(quat)
    sim.reset(q)
    mon.update()
    expected = np.zeros(mon.model.nq)
    mon._bridge.q_to_mj(sim.true_q(), expected)
    np.testing.assert_array_equal(mon.data.qpos, expected)
    for source in (np.arange(mon.model.nq), None):  # the general gather, and the way through pinocchio's q
        mon._qpos_source = source
        mon.data.qpos[:] = 0.0
        mon.update()
        np.testing.assert_array_equal(mon.data.qpos, expected)


def test_physical_contacts_act_and_are_counted(talos):
    sim = Simulator(talos, mode="spd", options=SimOptions(self_collision="physical"))
    assert sim.model.ngeom > Simulator(talos, mode="spd").model.ngeom
    sim.reset(_q_in_hip(talos))
    mujoco.mj_forward(sim.model, sim.data)
    mon = SelfCollisionMonitor(sim)
    assert mon.update()
    n = sim.data.ncon
    names = [mujoco.mj_id2name(sim.model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in sim.data.contact.geom1[:n]]
    active = [i for i, nm in enumerate(names) if nm and nm.startswith("selfcol:") and sim.data.contact.exclude[i] == 0]
    assert active


def test_probe_counts_events_and_ticks(talos):
    sim = Simulator(talos, mode="spd", options=SimOptions(self_collision="detect"))
    probe = SelfCollisionProbe()
    assert probe.attach(sim) == {"self_collision": ["pairs", "left", "right"]}
    probe.values()
    sim.reset(_q_in_hip(talos))
    v1 = probe.values()[0]
    probe.values()
    sim.reset()
    probe.values()
    m = probe.metrics({})
    assert v1[0] >= 1 and v1[1] == v1[0] and v1[2] == 0
    assert m["self_collisions"] == v1[0] and m["self_collision_ticks"] == 2
    assert all(k.startswith("left:") for k in m["self_collision_pairs"])


def test_errors(talos, g1, tmp_path):
    with pytest.raises(ConfigError, match="self_collision"):
        SimOptions(self_collision="yes")
    with pytest.raises(ConfigError, match="detect"):
        SelfCollisionMonitor(Simulator(talos, mode="spd"))
    data = yaml.safe_load(open(g1.profile.file).read())  # a profile without the section
    del data["collision_check"]
    (tmp_path / "g1-unchecked.yaml").write_text(yaml.safe_dump(data))
    unchecked = load_robot(str(tmp_path / "g1-unchecked.yaml"))
    with pytest.raises(ConfigError, match="collision_check"):
        Simulator(unchecked, mode="spd", options=SimOptions(self_collision="detect"))
