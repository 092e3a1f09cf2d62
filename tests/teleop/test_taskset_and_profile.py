"""Robot side of teleoperation, configuration: the profile's repulsors and collision check, the Table I task set,
the `self_collision` task type, the tsid-teleop controller's construction."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from wbcbench.tasks.registry import build_task
from wbcbench.controllers.taskset import load_taskset, taskset_path
from wbcbench.controllers.teleop import TSIDTeleop, teleop_taskset
from wbcbench.errors import ConfigError, UnknownNameError
from wbcbench.robots import Side, load_robot
from wbcbench.robots.profile import PROFILE_DIR
from wbcbench.tasks import SelfCollisionTask, update_kinematics

TABLE_I = {  # name: (mask, weight, kp) of paper 004 Table I
    "head": ((1, 1, 1, 0, 0, 0), 100, 8000), "head_pitch": ((0, 0, 0, 0, 1, 0), 100, 30),
    "head_yaw": ((0, 0, 0, 0, 0, 1), 100, 30), "left_hand": (None, 100, 8000), "right_hand": (None, 100, 8000),
    "torso": ((0, 0, 0, 1, 1, 0), 2000, 30), "com": ((1, 1, 0), 2e6, 3000), "posture": (None, 100.75, 30),
    "self_collision-left": (None, 700, 500), "self_collision-right": (None, 700, 500),
}


def test_table_i_is_shipped_as_published(talos):
    spec = load_taskset(taskset_path(talos, "teleop"), talos)
    assert {t.name for t in spec.tasks} == set(TABLE_I)
    for t in spec.tasks:
        mask, w, kp = TABLE_I[t.name]
        assert t.weight == w and np.all(t.kp == kp), t.name
        assert (t.mask is None and mask is None) or tuple(int(x) for x in t.mask) == mask, t.name
    assert spec.contacts.kp == 30
    assert spec.swing_foot.weight == 1000 and np.all(spec.swing_foot.kp == 30)   # Table I feet tasks


def test_profile_repulsors_become_self_collision_tasks(talos):
    rep = talos.profile.repulsors[Side.LEFT]
    assert rep.frame == "gripper_left_base_link" and rep.radius == 0.10 and rep.exponent == 3 and rep.normalized
    assert rep.offset == (0.0, 0.0, -0.09) and len(rep.points) == 18
    spec = load_taskset(taskset_path(talos, "teleop"), talos).task("self_collision-left")
    task = build_task(talos, spec)
    assert isinstance(task, SelfCollisionTask) and task.dim == 18 and task.weight == 700
    assert "thigh_left" in task.axis_names
    # half-sitting leaves the repulsors (nearly) idle
    m, d = talos.model, talos.model.createData()
    update_kinematics(m, d, talos.q0, np.zeros(m.nv))
    assert task.values(m, d).max() < 0.07
    assert set(talos.profile.collision_check) == set(Side)


def test_no_repulsors_drops_the_tasks(talos):
    assert not any(t.type == "self_collision" for t in teleop_taskset(talos, repulsors=False).tasks)
    ctrl = TSIDTeleop(talos, "spd", 1e-3, repulsors=False, stabilizer=False)
    assert not ctrl.repulsors and ctrl.stabilizer is None
    ctrl = TSIDTeleop(talos, "spd", 1e-3)
    assert ctrl.repulsors and ctrl.stabilizer is not None and ctrl.stabilizer.type == "force"


def _write(tmp_path: Path, name: str, data: dict) -> Path:
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data))
    return p


def test_self_collision_task_errors(talos, g1, tmp_path):
    base = yaml.safe_load(taskset_path(talos, "teleop").read_text())
    bad = dict(base, tasks=[{"name": "sc", "type": "self_collision", "weight": 1.0, "kp": 1.0}])
    with pytest.raises(ConfigError, match=r"tasks\[0\].*side.*required"):
        load_taskset(_write(tmp_path, "a.yaml", bad), talos)
    bad["tasks"][0]["side"] = "middle"
    with pytest.raises(ConfigError, match="allowed: left, right"):
        load_taskset(_write(tmp_path, "b.yaml", bad), talos)
    bad["tasks"][0]["side"] = "left"
    bad["tasks"][0]["mask"] = [1, 0, 1]
    with pytest.raises(ConfigError, match="18 entries"):
        load_taskset(_write(tmp_path, "c.yaml", bad), talos)
    bad["tasks"][0].pop("mask")
    bad["tasks"][0]["kp"] = [1.0, 2.0]
    with pytest.raises(ConfigError, match="18 values"):
        load_taskset(_write(tmp_path, "d.yaml", bad), talos)
    # a robot whose profile has no repulsors
    g1_set = {"tasks": [{"name": "sc", "type": "self_collision", "side": "left", "weight": 1.0, "kp": 1.0}],
              "contacts": {"kp": 30.0}, "swing_foot": {"weight": 1.0, "kp": 1.0}}
    data = yaml.safe_load(open(g1.profile.file).read())
    del data["repulsors"]
    bare = load_robot(str(_write(tmp_path, "g1-bare.yaml", data)))
    with pytest.raises(ConfigError, match="no `repulsors.left` section"):
        load_taskset(_write(tmp_path, "e.yaml", g1_set), bare)


def _profile_with(tmp_path, **sections) -> Path:
    data = yaml.safe_load((PROFILE_DIR / "talos.yaml").read_text())
    for k, v in sections.items():
        if v is None:
            data.pop(k, None)
        else:
            data[k] = v
    return _write(tmp_path, "talos-variant.yaml", data)


def test_profile_errors_name_file_and_key(talos, tmp_path):
    reps = yaml.safe_load((PROFILE_DIR / "talos.yaml").read_text())["repulsors"]
    bad = {"left": dict(reps["left"], points=[{"frame": "hip", "radius": 0.1}])}
    with pytest.raises(UnknownNameError, match=r"talos-variant.yaml.*repulsors.left.points\[0\].frame.*'hip'"):
        load_robot(str(_profile_with(tmp_path, repulsors=bad)))
    bad = {"left": dict(reps["left"], points=[])}
    with pytest.raises(ConfigError, match="at least one repulsion point"):
        load_robot(str(_profile_with(tmp_path, repulsors=bad)))
    bad = {"left": dict(reps["left"], exponent=1.0)}
    with pytest.raises(ConfigError, match="exponent.*>= 2"):
        load_robot(str(_profile_with(tmp_path, repulsors=bad)))
    bad = {"left": {"effector": ["gripper_left_base_link"], "bodies": ["thigh"]}}
    with pytest.raises(UnknownNameError, match="collision_check.left.bodies.*'thigh'"):
        load_robot(str(_profile_with(tmp_path, collision_check=bad)))
    bad = {"left": {"effector": ["base_link"], "bodies": ["base_link"]}}
    with pytest.raises(ConfigError, match="both effector and body"):
        load_robot(str(_profile_with(tmp_path, collision_check=bad)))
    # both sections are optional
    robot = load_robot(str(_profile_with(tmp_path, repulsors=None, collision_check=None)))
    assert robot.profile.repulsors == {} and robot.profile.collision_check == {}


def test_a_torque_limited_qp_at_its_iteration_limit_keeps_the_joint_limited_optimum(talos):
    """SPD mode: when the first QP's torques exceed a limit and the QP with the torque rows fails (here daqp at
    an iteration limit: the controller bounds that solve's time, `TORQUE_QP_ITERATIONS`), the tick keeps the
    first QP's optimum, counted in `qp_torque_rows_dropped_ticks`, with no relaxed QP and no fallback; the
    reset's warm-up solve is not counted."""
    from wbcbench.controllers.inverse_dynamics import QP_OK
    from wbcbench.qp import ActiveSetGuessSolver, DaqpSolver
    from wbcbench.sim.simulator import Simulator
    from wbcbench.types import ActuationMode, PointReference, References

    ctrl = TSIDTeleop(talos, ActuationMode.SPD, 1e-3)
    assert ctrl.torque_solver.backend.settings["iter_limit"] == TSIDTeleop.TORQUE_QP_ITERATIONS
    sim = Simulator(talos, mode=ctrl.mode)
    meas = sim.measure()
    m, d = talos.model, talos.model.createData()
    update_kinematics(m, d, meas.q, np.zeros(m.nv))
    com = d.com[0].copy()
    refs = References(t=0.0, com=PointReference(com), zmp=np.array([com[0], com[1], 0.0]))
    ctrl.reset(meas, refs)
    assert ctrl.n_torque_rows_dropped == 0
    F = ctrl.formulation
    F.tau_max = F.tau_max * 0.2  # below what standing takes: the torque rows bind, several iterations away
    ctrl.torque_solver = ActiveSetGuessSolver(DaqpSolver(iter_limit=1))
    ctrl.step(meas, refs)
    assert ctrl.n_torque_rows_dropped == 1 and ctrl.qp_status == QP_OK
    assert ctrl.n_relaxed == 0 and ctrl.n_fallback == 0
    # the kept optimum is the first QP's: its torques break the limits the torque rows could not impose
    assert np.any(np.abs(ctrl.tau) > F.tau_max * (1 + 1e-6))
    assert ctrl.status()["qp_torque_rows_dropped_ticks"] == 1


def _gripper_rushing_at_the_thigh(ctrl, talos, speed=3.0):
    """The QP of `ctrl` written at half-sitting with the left arm moving its gripper centre straight at the left
    thigh's repulsion point at `speed` [m/s] (1.45 a away), the left-hand reference 0.3 m further on (inside the
    thigh): a hand that lagged behind a fast operator and is pulled back across the body. Returns the formulation,
    the self-collision task, the thigh's row and v."""
    import pinocchio as pin_

    m, q = talos.model, talos.q0.copy()
    d = m.createData()
    task = ctrl.formulation.task_by_name["self_collision-left"]
    i = task.axis_names.index("thigh_left")
    spec = talos.profile.repulsors[Side.LEFT]
    pin_.computeJointJacobians(m, d, q)
    pin_.framesForwardKinematics(m, d, q)
    g = m.getFrameId(spec.frame)
    x = d.oMf[g].act(np.array(spec.offset))
    p = next(pt for pt in spec.points if pt.name == "thigh_left")
    target = d.oMf[m.getFrameId(p.frame)].act(np.array(p.offset))
    u = (target - x) / np.linalg.norm(target - x)
    J = pin_.getFrameJacobian(m, d, g, pin_.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
    J = J + pin_.skew(d.oMf[g].rotation @ np.array(spec.offset)).T @ \
        pin_.getFrameJacobian(m, d, g, pin_.ReferenceFrame.LOCAL_WORLD_ALIGNED)[3:]
    arm = [m.joints[m.getJointId(f"arm_left_{k}_joint")].idx_v for k in range(1, 5)]
    v = np.zeros(m.nv)
    v[arm] = np.linalg.pinv(J[:, arm]) @ (speed * u)
    F = ctrl.formulation
    F.update(q, v)
    F.reset_references(q, F.names)  # every task held at half-sitting
    hand = F.task_by_name["left_hand"]
    pin_.framesForwardKinematics(m, d, q)
    M = d.oMf[m.getFrameId(talos.profile.hands[Side.LEFT])]
    hand.set_reference(pin_.SE3(M.rotation, M.translation + 0.3 * u + (target - x)))
    return F, task, i, v


def test_the_repulsor_barrier_brakes_a_gripper_rushing_at_the_body(talos):
    """Table I's weighted repulsor rows act through grad C, tiny until the gripper is within about a of the
    repulsor: a hand task (kp 8000) pulling the gripper across the thigh at 3 m/s keeps accelerating it towards
    the thigh (the gripper-thigh contacts of public motion-capture recordings). The barrier rows (hard
    inequalities, C_ddot <= -kd_b C_dot + kp_b (C_max - C)) hold in the QP's solution and brake it; without them
    the same QP's solution breaks that bound."""
    from dataclasses import replace

    from wbcbench.qp import DaqpSolver
    from wbcbench.types import ActuationMode

    with_barrier = TSIDTeleop(talos, ActuationMode.TORQUE, 1e-3, stabilizer=False)
    spec = teleop_taskset(talos)
    soft = replace(spec, tasks=tuple(replace(t, options={**t.options, "barrier": None})
                                     if t.type == "self_collision" else t for t in spec.tasks))
    without = TSIDTeleop(talos, ActuationMode.TORQUE, 1e-3, taskset=soft, stabilizer=False)
    assert with_barrier.formulation.task_by_name["self_collision-left"].barrier is not None
    assert without.formulation.task_by_name["self_collision-left"].barrier is None
    accels = {}
    for name, ctrl in (("barrier", with_barrier), ("soft", without)):
        F, task, i, v = _gripper_rushing_at_the_thigh(ctrl, talos)
        m, d = talos.model, F.data
        res = DaqpSolver().solve(F.problem())
        assert res.ok, name
        dv = res.x[:m.nv]
        C, Cdot, drift = task.values(m, d)[i], task.velocity(m, d)[i], task.drift(m, d)[i]
        assert 0.01 < C < 0.1 and Cdot > 0.5  # 1.45 a away, closing fast
        clearance, kp_b, kd_b = with_barrier.formulation.task_by_name["self_collision-left"].barrier
        c_max = np.exp(-clearance**3)
        bound = -kd_b * Cdot + kp_b * (c_max - C)
        accels[name] = (task.jacobian(m, d)[i] @ dv + drift, bound)
    c_ddot, bound = accels["barrier"]
    assert c_ddot <= bound + 1e-6
    c_ddot, bound = accels["soft"]
    assert c_ddot > bound + 1.0  # the weighted rows alone let the approach go on
