"""tsid-teleop's out-of-reach caps: a hand's or the head's commanded acceleration scaled down while its target is
out of reach and moving (wbcbench/controllers/teleop.py, `_kernels.cap_task_accelerations`)."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.controllers._kernels import cap_task_accelerations

# e0, e1 [m], a_lin [m/s^2], a_ang [rad/s^2], v0, v1 [m/s], r0, r1 [rad], p0, p1 [m]: the position trigger only
P = np.array([0.10, 0.15, 20.0, 60.0, 0.2, 0.5, np.inf, np.inf, 0.20, 0.30])
P_ROT = np.array([0.10, 0.15, 20.0, 60.0, 0.2, 0.5, 0.15, 0.30, 0.20, 0.30])  # with the angular trigger
TALOS = np.array([0.10, 0.15, 20.0, 60.0, 0.2, 0.5, 0.10, 0.20, 0.20, 0.30])  # TALOS' teleop task set
ROWS = np.arange(6).reshape(1, 6)


def _rows(e_xyz, a_lin, a_ang, speed=2.0, drift=0.5):
    """One 6-axis task's stacked rows: errors, drift, reference velocity (along x), b = a* - drift."""
    e = np.array([*e_xyz, 0.1, 0.0, 0.0])
    d = np.full(6, drift)
    v = np.array([speed, 0.0, 0.0, 3.0, 0.0, 0.0])
    a = np.array([*a_lin, *a_ang], dtype=float)
    return e, d, v, a - d


def test_a_target_within_reach_is_left_alone():
    e, d, v, b = _rows([0.06, 0.0, 0.0], [400.0, 300.0, 0.0], [900.0, 0.0, 0.0])
    before = b.copy()
    assert cap_task_accelerations(b, d, e, v, ROWS, P) == 0
    assert np.array_equal(b, before)


def test_a_moving_target_out_of_reach_has_its_accelerations_capped_to_the_norms():
    e, d, v, b = _rows([0.0, 0.12, 0.09], [400.0, 300.0, 0.0], [900.0, 0.0, 0.0])  # |e| = 0.15, 2 m/s
    assert cap_task_accelerations(b, d, e, v, ROWS, P) == 1
    a = b + d
    assert np.allclose(a[:3], [16.0, 12.0, 0.0]) and np.allclose(a[3:], [60.0, 0.0, 0.0])


def test_the_cap_blends_continuously_in_the_error_and_in_the_reference_speed():
    def capped(en, speed):
        e, d, v, b = _rows([en, 0.0, 0.0], [500.0, 0.0, 0.0], [0.0, 0.0, 0.0], speed=speed)
        cap_task_accelerations(b, d, e, v, ROWS, P)
        return (b + d)[0]

    errors = [capped(x, 2.0) for x in (0.10, 0.1001, 0.125, 0.1499, 0.15)]
    assert errors[0] == pytest.approx(500.0) and errors[1] == pytest.approx(500.0, rel=1e-6)
    assert errors[2] == pytest.approx(260.0)  # half-way: the min-jerk blend at 1/2
    assert errors[3] == pytest.approx(20.0, rel=1e-4) and errors[4] == pytest.approx(20.0)
    assert all(x > y for x, y in zip(errors[1:], errors[2:]))
    # a still target out of reach (a hand the repulsors hold off a target inside the body) is left to the task
    speeds = [capped(0.3, s) for s in (0.0, 0.2, 0.35, 0.5, 4.0)]
    assert speeds[0] == speeds[1] == pytest.approx(500.0)
    assert speeds[2] == pytest.approx(260.0) and speeds[3] == speeds[4] == pytest.approx(20.0)


def test_a_small_commanded_acceleration_is_not_raised_and_unselected_axes_are_skipped():
    # a head-like task: position rows only (its rotation rows absent), at stack rows 4..6
    e, d, v, b = np.zeros(10), np.zeros(10), np.zeros(10), np.zeros(10)
    e[4:7] = [0.3, 0.0, 0.0]
    v[4:7] = [1.0, 0.0, 0.0]
    b[4:7] = [5.0, 0.0, 0.0]
    b[0] = 1e6  # another task's row
    rows = np.array([[4, 5, 6, -1, -1, -1]])
    assert cap_task_accelerations(b, d, e, v, rows, P) == 0
    assert b[4] == 5.0 and b[0] == 1e6
    b[4] = 50.0
    assert cap_task_accelerations(b, d, e, v, rows, P) == 1
    assert b[4] == pytest.approx(20.0) and b[0] == 1e6


def _turning(rot_err, ang_speed, e_xyz=(0.02, 0.0, 0.0)):
    """A tracked hand whose orientation reference turns away: rotation error about x, reference turning at
    `ang_speed` [rad/s] about x, position error `e_xyz`, commanded linear 160 m/s^2 and angular 4000 rad/s^2."""
    e = np.array([*e_xyz, rot_err, 0.0, 0.0])
    d = np.full(6, 0.5)
    v = np.array([0.1, 0.0, 0.0, ang_speed, 0.0, 0.0])
    a = np.array([160.0, 0.0, 0.0, 4000.0, 0.0, 0.0])
    return e, d, v, a - d


def test_an_orientation_turning_faster_than_the_wrist_has_its_angular_acceleration_capped_alone():
    # rotation error 0.4 rad, position tracked: the angular demand is capped to 60 rad/s^2 whether the reference
    # turns (10 rad/s) or has stopped (the cap not let go with the error still large), the linear one (the hand held
    # at its position reference) left alone
    for speed in (10.0, 1.0, 0.0):
        e, d, v, b = _turning(0.4, speed)
        assert cap_task_accelerations(b, d, e, v, ROWS, P_ROT) == 1
        assert np.allclose(b + d, [160.0, 0.0, 0.0, 60.0, 0.0, 0.0])
    # without the angular trigger (r0 = inf) the same rows are left alone, and so are a small rotation error (a
    # hand following a fast turn) with it, and an angular demand already under the cap
    for rot, params, a_ang in ((0.4, P, 4000.0), (0.14, P_ROT, 4000.0), (0.4, P_ROT, 50.0)):
        e, d, v, b = _turning(rot, 10.0)
        b[3] = a_ang - d[3]
        before = b.copy()
        assert cap_task_accelerations(b, d, e, v, ROWS, params) == 0 and np.array_equal(b, before)


def test_the_angular_trigger_blends_continuously_and_the_larger_trigger_wins():
    def angular(rot):
        e, d, v, b = _turning(rot, 10.0)
        cap_task_accelerations(b, d, e, v, ROWS, P_ROT)
        return (b + d)[3]

    rots = [angular(x) for x in (0.15, 0.1501, 0.225, 0.2999, 0.30, 1.0)]
    assert rots[0] == pytest.approx(4000.0) and rots[1] == pytest.approx(4000.0, rel=1e-6)
    assert rots[2] == pytest.approx(2030.0)  # half-way: (4000 + 60) / 2
    assert rots[3] == pytest.approx(60.0, rel=1e-3) and rots[4] == rots[5] == pytest.approx(60.0)
    assert all(x > y for x, y in zip(rots[1:4], rots[2:5]))
    # the position trigger half-way (|e| 0.125 m, the reference at 2 m/s) caps the linear demand half-way; the
    # angular one follows the larger of the two blends (the rotation trigger half-way, then full)
    e, d, v, b = _turning(0.225, 10.0, (0.125, 0.0, 0.0))
    v[0] = 2.0
    cap_task_accelerations(b, d, e, v, ROWS, P_ROT)
    assert (b + d)[0] == pytest.approx(90.0) and (b + d)[3] == pytest.approx(2030.0)
    e, d, v, b = _turning(0.4, 10.0, (0.125, 0.0, 0.0))
    v[0] = 2.0
    cap_task_accelerations(b, d, e, v, ROWS, P_ROT)
    assert (b + d)[0] == pytest.approx(90.0) and (b + d)[3] == pytest.approx(60.0)


def test_the_angular_trigger_lets_go_of_a_hand_far_from_its_position():
    # a hand held off a reference inside the body (position error 0.2-0.3 m and more, the reference still): the
    # angular trigger lets go as the position error grows from p0 to p1, so that its orientation keeps its demand
    def angular(en):
        e, d, v, b = _turning(0.4, 0.0, (en, 0.0, 0.0))
        v[0] = 0.0
        cap_task_accelerations(b, d, e, v, ROWS, P_ROT)
        return (b + d)[3]

    out = [angular(x) for x in (0.1, 0.2, 0.25, 0.3, 0.5)]
    assert out[0] == pytest.approx(60.0) and out[1] == pytest.approx(60.0)
    assert out[2] == pytest.approx(2030.0) and out[3] == pytest.approx(4000.0) and out[4] == pytest.approx(4000.0)


def _write_motion(tmp_path, name: str, description: str, duration: float, frames) -> object:
    """A synthetic operator motion through the keyframes `frames` [(t, {joint: deg})] written as a BVH file."""
    from wbcbench.teleop import write_bvh
    from wbcbench.teleop.synthetic import SyntheticMotion, _keyframes, motion_configurations

    motion = SyntheticMotion(name, description, "A", duration, 50.0, lambda t: _keyframes(t, frames))
    human, _, qs = motion_configurations(motion)
    return write_bvh(tmp_path / f"{name}.bvh", human.bvh_skeleton(0.01), human.bvh_motion(qs, 0.01), 1 / 50.0)


def test_arms_swung_behind_the_back_fell_without_the_cap_and_stand_with_it(talos, tmp_path):
    """An operator (a fixture of our own, written as BVH) swings both arms behind his back and then overhead,
    back and over again, 0.3 s a swing: the targets leave the reach of TALOS' arms (joint limits) while moving
    at metres per second. With kp 8000 the hand tasks asked for hundreds of m/s^2 and the weighted QP took them
    from the torso, pelvis and legs: TALOS fell (base below 0.6 m at 1.4 s). With the out-of-reach caps it
    stands to the end, the hands as close to their targets as before (0.26 against 0.28 m mean)."""
    from wbcbench.controllers.teleop import TSIDTeleop
    from wbcbench.runner import run
    from wbcbench.scenarios.teleop_kind import TeleopScenario
    from wbcbench.teleop import load_recording
    from wbcbench.teleop.synthetic import _both
    from wbcbench.types import ActuationMode

    behind, up = _both({"right_shoulder_Z": -80.0, "right_elbow_Z": 20.0}), _both({"right_shoulder_Z": 160.0,
                                                                                  "right_shoulder_X": 30.0})
    frames = [(0.3, {}), (0.6, behind), (0.9, up), (1.2, _both({"right_shoulder_Z": -80.0})),
              (1.5, _both({"right_shoulder_Z": 160.0})), (1.8, {})]
    path = _write_motion(tmp_path, "swing_back", "arms swung behind the back and overhead", 2.5, frames)
    out = {}
    for cap in (False, True):
        scen = TeleopScenario.from_source(talos, load_recording(path), duration=2.5, name="swing_back")
        ctrl = TSIDTeleop(talos, ActuationMode.SPD, scen.spec.control_dt, reach_cap=cap)
        summary = run(scen, ctrl, robot=talos, out=tmp_path / str(cap)).summary
        out[cap] = (summary["fell"], summary["sim_time_s"], summary["metrics"]["hand_position_error_m"]["mean"],
                    ctrl.formulation.n_capped_ticks)
    assert out[False][0] and out[False][1] < 2.0 and out[False][3] == 0
    assert not out[True][0] and out[True][1] == pytest.approx(2.5, abs=2e-3) and out[True][3] > 500
    assert out[True][2] < 0.3



def test_the_caps_come_from_the_task_set_and_bad_ones_are_one_line(talos, tmp_path):
    """TALOS' teleop task set carries the caps (`reach_cap:`), `reach_cap=False` leaves them off, and a task set
    whose caps name a task it does not have or give a range backwards is a ConfigError naming the file and key."""
    import yaml

    from wbcbench.controllers.taskset import load_taskset, taskset_path
    from wbcbench.controllers.teleop import TSIDTeleop
    from wbcbench.errors import ConfigError
    from wbcbench.types import ActuationMode

    on = TSIDTeleop(talos, ActuationMode.SPD, 1e-3)
    names, params = on.formulation.acceleration_caps
    assert on.reach_cap and set(names) == {"left_hand", "right_hand", "head"}
    np.testing.assert_array_equal(params, TALOS)
    with pytest.raises(ValueError, match="10 params"):  # the compiled kernel would read past a shorter array
        on.formulation.set_acceleration_caps(names, params[:6])
    off = TSIDTeleop(talos, ActuationMode.SPD, 1e-3, reach_cap=False)
    assert not off.reach_cap and off.formulation.acceleration_caps is None
    data = yaml.safe_load(taskset_path(talos, "teleop").read_text())
    no_rot = {k: v for k, v in data["reach_cap"].items() if k not in ("rotation", "rotation_within")}
    good = tmp_path / "teleop.yaml"
    good.write_text(yaml.safe_dump({**data, "reach_cap": no_rot}))
    assert load_taskset(good, talos).reach_cap.rotation is None
    np.testing.assert_array_equal(load_taskset(good, talos).reach_cap.params(), P)
    for change, key in (({"tasks": ["left_hand", "left_wrist"]}, r"reach_cap\.tasks\[1\]"),
                        ({"error": [0.15, 0.10]}, r"reach_cap\.error"), ({"linear": 0.0}, r"reach_cap\.linear"),
                        ({"rotation": [0.3, 0.15]}, r"reach_cap\.rotation"),
                        ({"rotation": [0.15]}, r"reach_cap\.rotation"),
                        ({"rotation": [-0.1, 0.2]}, r"reach_cap\.rotation"),
                        ({"rotation_within": [0.3, 0.3]}, r"reach_cap\.rotation_within"),
                        ({"rotation": None}, r"reach_cap\.rotation_within")):
        bad = tmp_path / "teleop.yaml"
        cap = {**data["reach_cap"], **change}
        bad.write_text(yaml.safe_dump({**data, "reach_cap": {k: v for k, v in cap.items() if v is not None}}))
        with pytest.raises(ConfigError, match=key) as exc:
            load_taskset(bad, talos)
        assert "teleop.yaml" in str(exc.value) and "\n" not in str(exc.value)


def test_a_wrist_flicked_faster_than_talos_wrist_no_longer_swings_the_gripper_off_its_position(talos, tmp_path):
    """An operator (a fixture of our own, written as BVH) holds his forearms forward and flicks both wrists up and
    down by 140 deg every 0.2 s, the hands' positions barely moving: the orientation references turn at the
    command filter's 10 rad/s, TALOS' wrist joints at about 2. Without the angular trigger (`reach_cap.rotation`) the
    QP turned the grippers with the shoulders, elbows and the body: the grippers swung up to 0.34 m off their
    position references and TALOS fell. With it the angular demand is capped while the rotation error is large:
    no fall, the grippers within 0.15 m of their positions (under 0.06 m on average)."""
    from wbcbench.controllers.teleop import TSIDTeleop
    from wbcbench.runner import run
    from wbcbench.scenarios.teleop_kind import TeleopScenario
    from wbcbench.teleop import load_recording
    from wbcbench.teleop.synthetic import _both
    from wbcbench.types import ActuationMode

    fwd = {"right_shoulder_Z": 50.0, "right_elbow_Z": 60.0}
    frames = [(0.2, {}), (0.7, _both(fwd))]
    for i in range(6):
        frames.append((0.9 + 0.2 * i, _both({**fwd, "right_wrist_Z": 70.0 if i % 2 == 0 else -70.0})))
    frames += [(2.3, _both(fwd))]
    path = _write_motion(tmp_path, "wrist_flick", "forearms forward, wrists flicked", 2.8, frames)
    out = {}
    for angular in (False, True):
        scen = TeleopScenario.from_source(talos, load_recording(path), duration=2.8, name="wrist_flick")
        ctrl = TSIDTeleop(talos, ActuationMode.SPD, scen.spec.control_dt)
        names, params = ctrl.formulation.acceleration_caps
        assert np.isfinite(params[6])  # TALOS' task set has the angular trigger
        if not angular:
            ctrl.formulation.set_acceleration_caps(names, np.concatenate([params[:6], [np.inf, np.inf], params[8:]]))
        summary = run(scen, ctrl, robot=talos, out=tmp_path / str(angular)).summary
        m = summary["metrics"]
        out[angular] = (summary["fell"], m["hand_position_error_m"]["mean"], m["hand_position_error_m"]["max"],
                        ctrl.formulation.n_capped_ticks)
    assert out[False][0] and out[False][2] > 0.3
    assert not out[True][0] and out[True][2] < 0.15 and out[True][1] < 0.06 and out[True][3] > 500
