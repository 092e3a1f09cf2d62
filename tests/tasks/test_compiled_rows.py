"""The compiled evaluations of task rows against pinocchio's: `log3`, the frame-task and contact batch of a stack
(`TaskStack(compiled_frames=True)`), the self-collision task's fused rows and joint accelerations, and the compiled
reference setters (same values stored, same errors)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.tasks import (
    CoMTask,
    Contact6D,
    FrameTask,
    ReferenceNotSetError,
    RepulsionPoint,
    SelfCollisionTask,
    TaskConfigError,
    TaskStack,
    update_kinematics,
)
from wbcbench.tasks.frame_batch import log3
from wbcbench.tasks.self_collision import _joint_accelerations

from .test_self_collision import REPULSORS



def test_log3_matches_pinocchio_from_zero_to_pi():
    rng = np.random.default_rng(3)
    out = np.empty(3)
    for k in range(400):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        theta = (rng.uniform(0.0, np.pi), rng.uniform(0.0, 1e-5), np.pi - rng.uniform(0.0, 1e-2), np.pi)[k % 4]
        R = pin.exp3(theta * axis)
        log3(R, out)
        ref = pin.log3(R)
        err = np.abs(out - ref).max()
        if theta == np.pi:  # +-pi axis are the same rotation
            err = min(err, np.abs(out + ref).max())
        assert err < (1e-6 if theta > np.pi - 1e-2 else 1e-10), (theta, out, ref)
        assert np.allclose(pin.exp3(out), R, atol=1e-9)


def _frame_tasks(model, rng):
    tasks = [
        FrameTask(model, "head_2_link", name="head", mask=[1, 1, 1, 0, 0, 0], kp=80.0),
        FrameTask(model, "head_2_link", name="head_pitch", mask=[0, 0, 0, 0, 1, 0], kp=30.0),
        FrameTask(model, "gripper_left_base_link", kp=50.0, weight=3.0),
        FrameTask(model, "torso_2_link", mask=[0, 0, 0, 1, 1, 0], kp=3.0),
        FrameTask(model, "arm_right_4_link", mask=[1, 0, 1, 0, 1, 1], kp=7.0),
    ]
    for t in tasks:
        t.set_reference(pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3)), rng.normal(size=6),
                        rng.normal(size=6))
    return tasks


def test_frame_batch_rows_match_pinocchio(erd_talos):
    m = erd_talos.model
    d = m.createData()
    rng = np.random.default_rng(0)
    tasks = _frame_tasks(m, rng)
    com = CoMTask(m, kp=10.0, mask=[1, 0, 1])
    com.set_reference(np.array([0.0, 0.1, 0.8]), np.array([0.1, 0.0, 0.2]))
    com_y = CoMTask(m, kp=4.0, kd=3.0, mask=[0, 1, 0], name="com_y")  # a second CoM task, its own reference
    com_y.set_reference(np.array([0.3, -0.2, 0.5]), None, np.array([0.0, 0.4, 0.0]))
    contacts = [Contact6D(m, "left_sole_link", length=0.2, width=0.1, kp=30.0),
                Contact6D(m, "right_sole_link", length=0.2, width=0.1, kp=30.0),
                Contact6D(m, "right_sole_link", length=0.2, width=0.1, kp=30.0, drift="classical", name="classical"),
                Contact6D(m, "left_sole_link", length=0.2, width=0.1, kp=30.0, error="split", name="split")]
    for c, angle in zip(contacts, (0.3, 2.5, 0.7, 0.4)):  # a small and a large rotation error
        c.set_reference(pin.SE3(pin.exp3(angle * np.array([0.6, 0.0, 0.8])), rng.normal(size=3)))
    stacked = [contacts[0], tasks[0], com, *tasks[1:], com_y, contacts[1], contacts[2], contacts[3]]
    plain = TaskStack(stacked, m.nv)
    batch = TaskStack(stacked, m.nv, compiled_frames=True)
    for seed in range(12):
        q, v = erd_talos.random_state(seed, speed=2.0)
        update_kinematics(m, d, q, v)
        A, b = (x.copy() for x in plain.acceleration_rows(m, d))
        A2, b2 = batch.acceleration_rows(m, d)
        assert np.allclose(A2, A, rtol=0, atol=1e-12 * (1 + np.abs(A).max()))
        assert np.allclose(b2, b, rtol=0, atol=1e-11 * (1 + np.abs(b).max()))
        bv = plain.velocity_rows(m, d).b.copy()
        assert np.allclose(batch.velocity_rows(m, d).b, bv, rtol=0, atol=1e-12 * (1 + np.abs(bv).max()))
    # a new reference and a new mask reach the batch, and a CoM reference shared between CoM tasks
    tasks[2].set_reference(pin.SE3.Identity())
    com_y.share_reference(com)
    tasks[3].mask = [1, 1, 1, 1, 1, 1]
    A, b = (x.copy() for x in plain.acceleration_rows(m, d))
    A2, b2 = batch.acceleration_rows(m, d)
    assert A2.shape == A.shape and np.allclose(b2, b, rtol=0, atol=1e-11 * (1 + np.abs(b).max()))


def test_joint_classical_accelerations_match_pinocchio(erd_talos):
    m = erd_talos.model
    d = m.createData()
    joints = [0, 1, 5, m.getJointId("arm_left_7_joint"), m.getJointId("head_2_joint")]
    masks = np.zeros((len(joints), m.nv), dtype=bool)
    for k, j in enumerate(joints):
        for s in m.supports[j]:
            if s > 0:
                masks[k, m.joints[s].idx_v:m.joints[s].idx_v + m.joints[s].nv] = True
    for seed in range(8):
        q, v = erd_talos.random_state(seed, speed=2.0)
        update_kinematics(m, d, q, v)
        origins = np.array([d.oMi[j].translation for j in joints])
        acc = np.empty((len(joints), 6))
        _joint_accelerations(d.J, d.dJ, v, masks, origins, acc)
        for k, j in enumerate(joints):
            ref = np.zeros(6) if j == 0 else pin.getClassicalAcceleration(
                m, d, j, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED).vector
            assert np.allclose(acc[k], ref, rtol=0, atol=1e-10 * (1 + np.abs(ref).max())), (j, acc[k], ref)


def test_self_collision_fused_rows_match_the_hooks_with_pinocchio_accelerations(erd_talos):
    m = erd_talos.model
    d = m.createData()
    options = dict(radius=0.25, offset=(0.0, 0.0, -0.09), kp=500.0, exponent=3.0, negligible=0.0)
    fused = SelfCollisionTask(m, "gripper_left_base_link", REPULSORS, **options)
    hooks = SelfCollisionTask(m, "gripper_left_base_link", REPULSORS, **options)
    stack = TaskStack([fused], m.nv)
    n = fused.dim
    for seed in range(10):
        q, v = erd_talos.random_state(seed, speed=2.0)
        update_kinematics(m, d, q, v)
        A, b = stack.acceleration_rows(m, d)
        J, e, drift = np.empty((n, m.nv)), np.empty(n), np.empty(n)
        hooks._write_jacobian(m, d, J)
        hooks._write_error(m, d, e)
        hooks._cache.origins = None  # the drift from pinocchio's getClassicalAcceleration
        hooks._write_drift(m, d, drift)
        assert np.allclose(A, J, rtol=0, atol=1e-12 * (1 + np.abs(J).max()))
        expected = fused.kp * e - fused.kd * (J @ v) - drift
        assert np.allclose(b, expected, rtol=0, atol=1e-10 * (1 + np.abs(expected).max()))
        # the public methods read the cache the fused call filled: the same numbers
        assert np.array_equal(fused.jacobian(m, d), A)
        assert np.allclose(fused.drift(m, d), drift, rtol=0, atol=1e-10 * (1 + np.abs(drift).max()))


def test_set_pose_stores_what_set_reference_stores_and_rejects_the_same(erd_talos):
    m = erd_talos.model
    rng = np.random.default_rng(1)
    a = FrameTask(m, "torso_2_link", kp=1.0)
    b = FrameTask(m, "torso_2_link", kp=1.0)
    R, p, w, acc = pin.exp3(rng.normal(size=3)), rng.normal(size=3), rng.normal(size=6), rng.normal(size=6)
    a.set_reference(pin.SE3(R, p), w, acc)
    b.set_pose(p, R, w, acc)
    for x, y in ((a.reference.rotation, b.reference.rotation), (a.reference.translation, b.reference.translation),
                 (a.v_ref, b.v_ref), (a.a_ref, b.a_ref)):
        assert np.array_equal(x, y)
    p[0] = 5.0  # copied, not aliased
    assert b.reference.translation[0] != 5.0
    b.set_pose(p, R)
    assert not b.v_ref.any() and not b.a_ref.any()
    b.set_pose(p + 1.0, None)  # a translating reference holds the orientation
    assert np.array_equal(b.reference.rotation, R) and np.array_equal(b.reference.translation, p + 1.0)
    with pytest.raises(ReferenceNotSetError, match="no orientation to hold"):
        FrameTask(m, "torso_2_link", kp=1.0).set_pose(p, None)
    with pytest.raises(TaskConfigError, match="rotation"):
        b.set_pose(p, R * 1.1)
    with pytest.raises(TaskConfigError, match="velocity"):
        b.set_pose(p, R, np.full(6, np.nan))
    with pytest.raises(TaskConfigError):
        b.set_pose(np.array([np.nan, 0.0, 0.0]), R)
    b.set_pose([1, 2, 3], R.tolist())  # lists take the general path
    assert np.array_equal(b.reference.translation, [1.0, 2.0, 3.0])


def test_compiled_com_and_contact_setters_check_like_before(erd_talos):
    m = erd_talos.model
    com = CoMTask(m, kp=1.0)
    com.set_reference(np.array([0.1, 0.0, 0.8]), np.array([0.0, 0.1, 0.0]), np.zeros(3))
    assert np.array_equal(com.reference, [0.1, 0.0, 0.8]) and np.array_equal(com.v_ref, [0.0, 0.1, 0.0])
    for bad in ((np.array([np.inf, 0.0, 0.0]), None, None), (np.zeros(3), np.array([0.0, np.nan, 0.0]), None)):
        with pytest.raises(TaskConfigError):
            com.set_reference(*bad)
    contact = Contact6D(m, "left_sole_link", length=0.2, width=0.1, kp=1.0)
    R = pin.exp3(np.array([0.0, 0.1, 0.2]))
    contact.set_reference(pin.SE3(R, np.array([0.0, 0.1, 0.0])))
    assert np.array_equal(contact.reference.rotation, R)
    with pytest.raises(TaskConfigError, match="rigid transform"):
        contact.set_reference(pin.SE3(R * 2.0, np.zeros(3)))


def test_tsid_teleop_commands_are_the_same_with_pinocchios_rows(talos):
    """tsid-teleop evaluates its frame and self-collision rows compiled: on the same measurements its commands
    equal those of the same controller on pinocchio's frame rows, to rounding."""
    from wbcbench.controllers.teleop import TSIDTeleop
    from wbcbench.sim.simulator import Simulator
    from wbcbench.types import PointReference, References

    class PinocchioRows(TSIDTeleop):
        compiled_frames = False

    compiled = TSIDTeleop(talos, TSIDTeleop.default_mode, 1e-3)
    plain = PinocchioRows(talos, TSIDTeleop.default_mode, 1e-3)
    assert compiled.formulation.compiled_frames and not plain.formulation.compiled_frames
    sim = Simulator(talos, mode=compiled.mode)
    meas = sim.measure()
    data = talos.model.createData()
    com = pin.centerOfMass(talos.model, data, meas.q).copy()
    refs = References(t=0.0, com=PointReference(com), zmp=np.array([com[0], com[1], 0.0]))
    compiled.reset(meas, refs)
    plain.reset(meas, refs)
    worst = 0.0
    for k in range(150):
        a, b = compiled.step(meas, refs), plain.step(meas, refs)
        worst = max(worst, float(np.abs(a.q - b.q).max()))
        sim.apply(a)
        sim.step()
        meas = sim.measure()
    assert worst < 1e-9, worst


@pytest.mark.parametrize("name", ["tsid-torque", "tsid-position", "ik"])
def test_paper_controllers_commands_are_the_same_with_pinocchios_rows(talos, name):
    """The paper's controllers evaluate their frame, contact and CoM rows compiled: walking into the first single
    support of a plan (CoM moving over a foot, a contact schedule), their commands equal those of the same
    controller on pinocchio's rows, to rounding."""
    from wbcbench.controllers.base import make_controller
    from wbcbench.scenarios import load_scenario
    from wbcbench.side import Side
    from wbcbench.sim.simulator import Simulator

    compiled = make_controller(name, talos, None, 1e-3)
    plain = make_controller(name, talos, None, 1e-3)
    plain.formulation.compiled_frames = False
    assert compiled.formulation.compiled_frames
    scenario = load_scenario("walk-20cm-quick", talos)
    sim = Simulator(talos, mode=compiled.mode)
    meas = sim.measure()
    scenario.setup(meas.q, pin.centerOfMass(talos.model, talos.model.createData(), meas.q))
    lift_off = min(int(np.flatnonzero(~np.asarray(scenario.walk.feet[s].in_contact, dtype=bool))[0]) for s in Side)
    refs = scenario.references(meas.t)
    compiled.reset(meas, refs)
    plain.reset(meas, refs)
    worst = 0.0
    for k in range(lift_off + 300):  # into the first single support
        refs = scenario.references(meas.t)
        a, b = compiled.step(meas, refs), plain.step(meas, refs)
        x, y = (a.tau, b.tau) if a.tau is not None else (a.q, b.q)
        worst = max(worst, float(np.abs(x - y).max() / (1.0 + np.abs(y).max())))
        sim.apply(a)
        sim.step()
        meas = sim.measure()
    assert worst < 1e-9, worst
