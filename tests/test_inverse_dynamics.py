"""The inverse-dynamics controller (TSID-like weighted QP): dynamics consistency, contact wrenches, task
semantics, the sway and one-foot scenarios, bad task files and QP failures."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.controllers.inverse_dynamics import QP_FALLBACK, QP_OK, QP_RELAXED, TSIDPosition, TSIDTorque
from wbcbench.controllers.taskset import TaskSpec, load_taskset, taskset_path
from wbcbench.errors import ConfigError
from wbcbench.qp import QPResult, QPStatus
from wbcbench.runner import run
from wbcbench.side import Side
from wbcbench.sim.model import ActuationMode
from wbcbench.sim.simulator import Simulator
from wbcbench.types import PointReference, PoseReference, References



def _controller(robot, cls=TSIDTorque, mode=ActuationMode.TORQUE, taskset=None):
    sim = Simulator(robot, mode=mode)
    if taskset is None and cls is TSIDPosition:  # these ticks give no ZMP plan: no DCM stabilizer
        taskset = replace(load_taskset(taskset_path(robot, cls.name), robot), stabilizer=None)
    ctrl = cls(robot, mode, 1e-3, taskset)
    meas = sim.measure()
    ctrl.reset(meas, References(t=0.0))
    return sim, ctrl, meas


def _check_tick(ctrl, q, v):
    """M dv + h = S^T tau + sum J_c^T w, wrenches in their cones, on the state the QP used."""
    m, d = ctrl.model, ctrl.data
    rhs = np.concatenate([np.zeros(6), ctrl.tau])
    for s in Side:
        c = ctrl.contacts[s]
        if c.active:
            J = pin.getFrameJacobian(m, d, c.contact.frame_id, pin.LOCAL)
            rhs += J.T @ ctrl.wrench[s]
            assert c.contact.inside(ctrl.wrench[s], tol=1e-7), (s, ctrl.wrench[s])
            cop = c.contact.cop(ctrl.wrench[s])
            sole = ctrl.robot.profile.sole
            assert abs(cop[0] - sole.center[0]) <= sole.length / 2 + 1e-9
            assert abs(cop[1] - sole.center[1]) <= sole.width / 2 + 1e-9
        else:
            assert np.all(ctrl.wrench[s] == 0)
    M = pin.crba(m, m.createData(), q)
    M = np.triu(M) + np.triu(M, 1).T
    lhs = M @ ctrl.dv + pin.nonLinearEffects(m, m.createData(), q, v)
    assert np.abs(lhs - rhs).max() < 1e-8


def test_dynamics_consistency_and_wrenches_every_tick(talos):
    """One second of lateral sway in closed loop, then the shift onto one foot: every solved tick is
    dynamically consistent to 1e-8 and its wrenches are inside their friction pyramids and soles."""
    from wbcbench.scenarios import load_scenario

    sim, ctrl, meas = _controller(talos)
    for name, T in (("sway", 1.0), ("one-foot", 2.0)):
        scen = load_scenario(name, talos)
        sim.reset()
        meas = sim.measure()
        scen.setup(meas.q, pin.centerOfMass(talos.model, talos.model.createData(), meas.q))
        ctrl.reset(meas, scen.references(0.0))
        for k in range(int(T / 1e-3)):
            refs = scen.references(k * 1e-3)
            cmd = ctrl.step(meas, refs)
            assert ctrl.qp_status == QP_OK
            _check_tick(ctrl, meas.q, meas.v)
            sim.apply(cmd)
            sim.step()
            meas = sim.measure()
    # at the end of one-foot the right contact has been ramped out
    assert not ctrl.contacts[Side.RIGHT].active


def _solve_once(robot, taskset, com_ref=None):
    sim, ctrl, meas = _controller(robot, taskset=taskset)
    refs = References(t=0.0)
    if com_ref is not None:
        refs = References(t=0.0, com=PointReference(com_ref))
    ctrl.step(meas, refs)
    return ctrl.dv.copy(), {s: w.copy() for s, w in ctrl.wrench.items()}


def test_zero_weight_task_changes_nothing(talos):
    spec = load_taskset(taskset_path(talos, "tsid-torque"), talos)
    hand = TaskSpec(name="hand", type="frame", weight=0.0, kp=np.full(6, 100.0), kd=None,
                    options={"frame": talos.profile.hands[Side.LEFT]})
    with_hand = replace(spec, tasks=spec.tasks + (hand,))
    dv0, w0 = _solve_once(talos, spec, com_ref=np.array([0.01, 0.02, 0.87]))
    dv1, w1 = _solve_once(talos, with_hand, com_ref=np.array([0.01, 0.02, 0.87]))
    assert np.abs(dv0 - dv1).max() < 1e-9
    # and the same task with a weight does change the solution (the test can fail)
    weighted = replace(spec, tasks=spec.tasks + (replace(hand, weight=10.0),))
    sim, ctrl, meas = _controller(talos, taskset=weighted)
    ctrl.task_by_name["hand"].set_reference(pin.SE3(np.eye(3), np.array([0.3, 0.3, 1.2])))
    ctrl.step(meas, References(t=0.0, com=PointReference([0.01, 0.02, 0.87])))
    assert np.abs(ctrl.dv - dv0).max() > 1e-3


def test_wrench_axis_weights_move_the_cop_between_the_feet(talos):
    """A lateral CoM reference in double support needs a roll moment about the feet's midpoint. With every wrench
    axis weighted 1 a newton metre of sole moment is as cheap as a newton, so the feet twist (ankle roll torques);
    with the shipped weights (moments 2, normal force 0.1, after TSID's Contact6d) the QP shifts normal force
    to one foot instead, with far smaller sole moments and ankle roll torques."""
    spec = load_taskset(taskset_path(talos, "tsid-torque"), talos)
    assert spec.regularization_wrench_axes == (1.0, 1.0, 0.1, 2.0, 2.0, 2.0)
    uniform = replace(spec, regularization_wrench_axes=(1.0,) * 6)
    com = np.array([0.0, 0.04, 0.87])
    out = {}
    for name, ts in (("uniform", uniform), ("shipped", spec)):
        sim, ctrl, meas = _controller(talos, taskset=ts)
        ctrl.step(meas, References(t=0.0, com=PointReference(com)))
        _check_tick(ctrl, meas.q, meas.v)
        roll = [talos.joint_names.index(f"leg_{s.value}_6_joint") for s in Side]
        out[name] = (ctrl.wrench[Side.LEFT].copy(), ctrl.wrench[Side.RIGHT].copy(), np.abs(ctrl.tau[roll]).sum())
    (lu, ru, roll_u), (lt, rt, roll_t) = out["uniform"], out["shipped"]
    assert abs(lt[2] - rt[2]) > 4 * abs(lu[2] - ru[2])  # the normal force now differs between the feet
    assert abs(lt[3]) + abs(rt[3]) < 0.4 * (abs(lu[3]) + abs(ru[3]))  # and the sole roll moments shrink
    assert roll_t < 0.3 * roll_u


def test_contact_options_from_the_task_set(talos, tmp_path):
    """contacts.drift and contacts.wrench_metric reach the controller's contacts; the shipped diagonal given as a
    full 6 x 6 metric gives the same tick (the same QP), and TSID's metric ({form: tsid}) a different, consistent
    one."""
    text = taskset_path(talos, "tsid-torque").read_text()
    reg = "regularization: {dv: 1.0e-6, wrench: 1.0e-5, wrench_axes: [1.0, 1.0, 0.1, 2.0, 2.0, 2.0]}"
    assert reg in text
    diag = np.diag(1e-5 * np.array([1.0, 1.0, 0.1, 2.0, 2.0, 2.0]) ** 2)
    full = text.replace(reg, "regularization: {dv: 1.0e-6}").replace(
        "  kp: 30.0\n", f"  kp: 30.0\n  drift: classical\n  error: split\n  wrench_metric: {diag.tolist()}\n")
    tsid = text.replace(reg, "regularization: {dv: 1.0e-6}").replace(
        "  kp: 30.0\n", "  kp: 30.0\n  wrench_metric: {form: tsid, weight: 1.0e-5}\n")
    com = PointReference([0.0, 0.03, 0.87])
    out = {}
    for name, body in (("shipped", text), ("full", full), ("tsid", tsid)):
        p = tmp_path / f"{name}.yaml"
        p.write_text(body)
        sim, ctrl, meas = _controller(talos, taskset=load_taskset(p, talos))
        ctrl.step(meas, References(t=0.0, com=com))
        _check_tick(ctrl, meas.q, meas.v)
        out[name] = (ctrl.dv.copy(), ctrl.contacts[Side.LEFT].contact, ctrl.wrench[Side.LEFT].copy())
    assert out["shipped"][1].drift_convention == "spatial" and out["shipped"][1].wrench_metric is None
    assert out["full"][1].drift_convention == "classical" and np.array_equal(out["full"][1].wrench_metric, diag)
    assert out["full"][1].error_convention == "split" and out["shipped"][1].error_convention == "log6"
    assert np.abs(out["full"][0] - out["shipped"][0]).max() < 1e-9  # at rest the two drifts (and errors) agree
    assert np.abs(out["tsid"][2] - out["shipped"][2]).max() > 1.0  # [N]: the feet share the load otherwise


def test_masked_axis_is_left_free(talos):
    """With only the x-y CoM task (height axis masked out), the CoM height reference has no effect."""
    spec = load_taskset(taskset_path(talos, "tsid-torque"), talos)
    xy_only = replace(spec, tasks=tuple(t for t in spec.tasks if t.name != "com_z"))
    dv_a, _ = _solve_once(talos, xy_only, com_ref=np.array([0.0, 0.0, 0.80]))
    dv_b, _ = _solve_once(talos, xy_only, com_ref=np.array([0.0, 0.0, 0.95]))
    assert np.abs(dv_a - dv_b).max() < 1e-9
    dv_c, _ = _solve_once(talos, xy_only, com_ref=np.array([0.0, 0.03, 0.80]))
    assert np.abs(dv_a - dv_c).max() > 1e-3
    # with the height task back, the height reference matters
    dv_d, _ = _solve_once(talos, spec, com_ref=np.array([0.0, 0.0, 0.80]))
    dv_e, _ = _solve_once(talos, spec, com_ref=np.array([0.0, 0.0, 0.95]))
    assert np.abs(dv_d - dv_e).max() > 1e-3


@pytest.mark.parametrize("controller", ["tsid-torque", "tsid-position"])
def test_sway_tracks_the_com_within_1cm(talos, tmp_path, controller):
    res = run("sway", controller, talos, duration=10.0, out=tmp_path)
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    assert s["metrics"]["com_rms_error_m"] < 0.01
    assert s["controller_status"]["qp_fallback_ticks"] == 0
    # the CoM really moved: +-5 cm peak to peak about 10 cm laterally
    y = res.log["com.y"]
    assert y.max() - y.min() > 0.08


def test_one_foot_balance(talos, tmp_path):
    res = run("one-foot", "tsid-torque", talos, duration=5.0, out=tmp_path)
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    log = res.log
    # the right foot carries nothing at the end and has been lifted about 5 cm
    assert abs(log["contact_right.fz"][-1]) < 1e-6
    q = np.column_stack([log[c] for c in log if c.startswith("q.")])[-1]
    d = talos.model.createData()
    pin.framesForwardKinematics(talos.model, d, q)
    z = d.oMf[talos.sole_frame_id(Side.RIGHT)].translation[2]
    assert z == pytest.approx(0.05, abs=0.005)
    assert log["contact_left.fz"][-1] == pytest.approx(talos.mass * 9.81, rel=0.02)


def test_qp_failure_falls_back_to_a_safe_command(talos, monkeypatch):
    sim, ctrl, meas = _controller(talos)
    fail = QPResult.failure(QPStatus.INFEASIBLE, solver="daqp", raw_status=-1)
    monkeypatch.setattr(ctrl.solver, "solve", lambda p: fail)
    monkeypatch.setattr(ctrl.relaxed_solver, "solve", lambda p: fail)
    cmd = ctrl.step(meas, References(t=0.0))
    assert ctrl.qp_status == QP_FALLBACK and ctrl.status()["qp_fallback_ticks"] == 1
    # the fallback is the joint-pd law about the current posture: it holds the robot (finite, within limits)
    assert np.all(np.isfinite(cmd.tau)) and np.all(np.abs(cmd.tau) <= talos.effort_limit * 10)
    from wbcbench.controllers.joint_pd import JointPD
    ref = JointPD(talos, ActuationMode.TORQUE, 1e-3)
    ref.q_ref = meas.q[7:]
    assert np.allclose(cmd.tau, ref.step(meas, References(t=0.0)).tau)


def test_infeasible_limits_are_relaxed_and_logged(talos, tmp_path):
    """Joints locked by their position limits and torque limits far too low to stand: the QP is infeasible,
    so it is solved again without the limit rows, and says so."""
    sim, ctrl, meas = _controller(talos)
    F = ctrl.formulation
    F.tau_max = np.full(talos.na, 1.0)
    F.q_lo, F.q_hi = meas.q[7:] - 1e-9, meas.q[7:] + 1e-9
    ctrl.step(meas, References(t=0.0))
    assert ctrl.qp_status == QP_RELAXED and ctrl.status()["qp_relaxed_ticks"] == 1
    _check_tick(ctrl, meas.q, meas.v)


def _bad_taskset(tmp_path, talos, old, new):
    text = taskset_path(talos, "tsid-torque").read_text()
    assert old in text
    p = tmp_path / "tasks.yaml"
    p.write_text(text.replace(old, new))
    return p


@pytest.mark.parametrize("old,new,needles", [
    ("frame: base,", "frame: torso_9_link,", ["tasks[2].frame", "torso_9_link"]),
    ("type: angular_momentum,", "type: angular_momentom,", ["tasks[3].type", "angular_momentum", "unknown task type"]),
    ("mask: [0, 0, 1]", "mask: [0, 1]", ["tasks[1].mask", "3 entries"]),
    ("weight: 0.02, kp: 10.0", "weight: 0.02, kp: -10.0", ["tasks[3].kp", ">= 0"]),
    ("weight: 1.0, kp: 100.0", "weight: -1.0, kp: 100.0", ["tasks[2].weight", ">= 0"]),
    ("  kp: 30.0\n", "  kp: 30.0\n  kq: 1.0\n", ["contacts.kq", "unknown key"]),
    ("wrench_axes: [1.0, 1.0, 0.1, 2.0, 2.0, 2.0]", "wrench_axes: [1.0, 1.0, 2.0]",
     ["regularization.wrench_axes", "6 values"]),
    ("wrench_axes: [1.0, 1.0, 0.1,", "wrench_axes: [1.0, 1.0, -0.1,", ["regularization.wrench_axes", ">= 0"]),
    ("pitch_with_leg: true", "pitch_with_leg: 1", ["swing_foot.pitch_with_leg", "true or false"]),
    ("  kp: 30.0\n", "  kp: 30.0\n  drift: exact\n", ["contacts.drift", "'exact'", "spatial, classical"]),
    ("  kp: 30.0\n", "  kp: 30.0\n  error: se3\n", ["contacts.error", "'se3'", "log6, split"]),
    ("  kp: 30.0\n", "  kp: 30.0\n  wrench_metric: [[1, 0], [0, 1]]\n", ["contacts.wrench_metric", "6 x 6"]),
    ("  kp: 30.0\n", "  kp: 30.0\n  wrench_metric: {form: tsdi}\n", ["contacts.wrench_metric.form", "tsid"]),
    ("  kp: 30.0\n", "  kp: 30.0\n  wrench_metric: {form: tsid}\n", ["regularization.wrench", "one or the other"]),
    ("solver: daqp", "solver: daqp\nservo_feedforward: legs", ["servo_feedforward", "'legs'", "all_but_ankles"]),
])
def test_bad_task_files_name_file_and_key(talos, tmp_path, old, new, needles):
    p = _bad_taskset(tmp_path, talos, old, new)
    with pytest.raises(ConfigError) as err:
        load_taskset(p, talos)
    msg = str(err.value)
    assert str(p) in msg
    for n in needles:
        assert n in msg, msg


def test_position_mode_feeds_back_the_integrated_state(talos):
    """TSID position: the QP runs on its own integrated state, not on the measurement (paper Section 3.3)."""
    sim, ctrl, meas = _controller(talos, TSIDPosition, ActuationMode.POSITION)
    refs = References(t=0.0)
    cmd = ctrl.step(meas, refs)
    q1 = ctrl.q_int.copy()
    bogus = replace(meas, q=meas.q + np.concatenate([[0.1, 0, 0], np.zeros(talos.nq - 3)]))
    ctrl.step(bogus, refs)
    ctrl2 = TSIDPosition(talos, ActuationMode.POSITION, 1e-3, ctrl.spec)
    ctrl2.reset(meas, refs)
    ctrl2.step(meas, refs)
    ctrl2.step(meas, refs)
    assert np.allclose(ctrl.q_int, ctrl2.q_int, atol=1e-12)
    assert np.allclose(cmd.q, q1[7:])


@pytest.mark.parametrize("mode", [ActuationMode.POSITION, ActuationMode.SPD])
def test_servo_feedforward_hands_the_qp_torques_to_the_servos(talos, mode):
    """`servo_feedforward: all_but_ankles`: position mode offsets each set point by the QP torque over the servo's kp
    (the ankles, the two joints nearest each sole, keep theirs); SPD mode sends the same torques as its feed-forward;
    `none` leaves the command as it was."""
    spec = replace(load_taskset(taskset_path(talos, "tsid-position"), talos), stabilizer=None)
    refs = References(t=0.0)
    sim, plain, meas = _controller(talos, TSIDPosition, mode, taskset=replace(spec, servo_feedforward="none"))
    cmd0 = plain.step(meas, refs)
    _, ctrl, _ = _controller(talos, TSIDPosition, mode, taskset=replace(spec, servo_feedforward="all_but_ankles"))
    cmd = ctrl.step(meas, refs)
    kp, _ = talos.profile.position_gains.resolve(talos.joint_names, talos.profile.file)
    ankles = [talos.joint_names.index(f"leg_{s}_{i}_joint") for s in ("left", "right") for i in (5, 6)]
    fed = np.ones(talos.na, bool)
    fed[ankles] = False
    assert np.array_equal(ctrl.q_int, plain.q_int) and np.array_equal(ctrl.tau, plain.tau)
    assert np.abs(ctrl.tau[~fed]).min() > 0.1  # the ankles carry load: leaving them out is visible
    assert cmd0.tau is None and np.array_equal(cmd0.q, plain.q_int[7:])
    if mode is ActuationMode.POSITION:
        assert cmd.tau is None
        assert np.allclose(cmd.q - ctrl.q_int[7:], np.where(fed, ctrl.tau / kp, 0.0), rtol=0, atol=1e-15)
    else:
        assert np.array_equal(cmd.q, ctrl.q_int[7:])
        assert np.array_equal(cmd.tau, np.where(fed, ctrl.tau, 0.0))


def test_named_frame_targets_drive_their_task(talos):
    """References.targets sets a named frame task's reference: a weighted hand task pulls the hand."""
    spec = load_taskset(taskset_path(talos, "tsid-torque"), talos)
    hand = TaskSpec(name="left_hand", type="frame", weight=100.0, kp=np.full(6, 100.0), kd=None,
                    mask=(True, True, True, False, False, False), options={"frame": talos.profile.hands[Side.LEFT]})
    sim, ctrl, meas = _controller(talos, taskset=replace(spec, tasks=spec.tasks + (hand,)))
    target = ctrl.task_by_name["left_hand"].placement(ctrl.model, ctrl.data)
    target.translation += np.array([0.1, 0.0, 0.1])
    refs = References(t=0.0, targets={"left_hand": PoseReference.from_se3(target)})
    fid = talos.model.getFrameId(talos.profile.hands[Side.LEFT])
    d = talos.model.createData()
    pin.framesForwardKinematics(talos.model, d, meas.q)
    e0 = np.linalg.norm(d.oMf[fid].translation - target.translation)
    for _ in range(1000):
        cmd = ctrl.step(meas, refs)
        sim.apply(cmd)
        sim.step()
        meas = sim.measure()
    pin.framesForwardKinematics(talos.model, d, meas.q)
    assert np.linalg.norm(d.oMf[fid].translation - target.translation) < 0.2 * e0


def test_a_leaving_contact_is_unloaded_by_its_planned_lift_off(talos):
    """With `unload_before_lift_off`, a contact whose planned lift-off (`References.lift_off`) is within the
    transition time ramps its maximum normal force to zero at that time, stays (unloaded) while still wanted, is
    removed once not wanted, and ramps back in if the lift-off moves further ahead. Off, the lift-off is ignored."""
    spec = load_taskset(taskset_path(talos, "tsid-torque"), talos)
    assert spec.contacts.transition_time == pytest.approx(0.05)
    on = replace(spec, contacts=replace(spec.contacts, unload_before_lift_off=True))
    off = replace(spec, contacts=replace(spec.contacts, unload_before_lift_off=False))
    both, left = frozenset(Side), frozenset({Side.LEFT})
    R = Side.RIGHT

    sim, ctrl, meas = _controller(talos, taskset=off)
    ctrl.step(meas, References(t=0.0, contacts=both, lift_off={R: 0.03}))
    assert ctrl.contacts[R].contact.max_normal_force == pytest.approx(spec.contacts.max_normal_force)

    sim, ctrl, meas = _controller(talos, taskset=on)
    ctrl.step(meas, References(t=0.0, contacts=both))  # no lift-off ahead: both loaded
    f0 = ctrl.wrench[R][2]
    assert f0 > 300.0
    fz = []
    for k in range(1, 6):  # lift-off planned at 0.04 s: the ramp starts at 0.01 s from the current load
        t = k * 0.01
        wanted = both if t < 0.04 else left
        ctrl.step(replace(meas, t=t), References(t=t, contacts=wanted, lift_off={R: 0.04} if t < 0.04 else {}))
        _check_tick(ctrl, meas.q, meas.v)
        fz.append(ctrl.wrench[R][2])
        if t < 0.04:
            assert ctrl.contacts[R].active
            assert ctrl.contacts[R].contact.max_normal_force == pytest.approx(f0 * (0.04 - t) / 0.03, rel=1e-6)
            assert fz[-1] <= f0 * (0.04 - t) / 0.03 + 1e-6
    assert not ctrl.contacts[R].active and fz[-2:] == [0.0, 0.0]
    assert fz[0] == pytest.approx(f0, rel=0.05)  # ramp start: from the load, not a jump

    # the lift-off moves ahead (a re-plan) while unloading: the contact ramps back in
    sim, ctrl, meas = _controller(talos, taskset=on)
    ctrl.step(meas, References(t=0.0, contacts=both))
    for t in (0.01, 0.02):
        ctrl.step(replace(meas, t=t), References(t=t, contacts=both, lift_off={R: 0.03}))
    assert ctrl.contacts[R].contact.max_normal_force == pytest.approx(f0 / 2, rel=0.05)
    ctrl.step(replace(meas, t=0.03), References(t=0.03, contacts=both, lift_off={R: 1.0}))
    assert ctrl.contacts[R].contact.max_normal_force == pytest.approx(f0 / 2, rel=0.05)  # from where it was
    ctrl.step(replace(meas, t=0.08), References(t=0.08, contacts=both, lift_off={R: 1.0}))
    assert ctrl.contacts[R].active
    assert ctrl.contacts[R].contact.max_normal_force == pytest.approx(spec.contacts.max_normal_force)
