"""tsid-teleop's out-of-reach caps: a hand's or the head's commanded acceleration scaled down while its target is
out of reach and moving (wbcbench/controllers/teleop.py, `_kernels.cap_task_accelerations`)."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.controllers._kernels import cap_task_accelerations

P = np.array([0.10, 0.15, 20.0, 60.0, 0.2, 0.5])  # e0, e1 [m], a_lin [m/s^2], a_ang [rad/s^2], v0, v1 [m/s]
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


def test_arms_swung_behind_the_back_fell_without_the_cap_and_stand_with_it(talos, tmp_path):
    """An operator (a fixture of our own, written as BVH) swings both arms behind his back and then overhead,
    back and over again, 0.3 s a swing: the targets leave the reach of TALOS' arms (joint limits) while moving
    at metres per second. With kp 8000 the hand tasks asked for hundreds of m/s^2 and the weighted QP took them
    from the torso, pelvis and legs: TALOS fell (base below 0.6 m at 1.4 s). With the out-of-reach caps it
    stands to the end, the hands as close to their targets as before (0.26 against 0.28 m mean)."""
    from wbcbench.controllers.teleop import TSIDTeleop
    from wbcbench.runner import run
    from wbcbench.scenarios.teleop_kind import TeleopScenario
    from wbcbench.teleop import load_recording, write_bvh
    from wbcbench.teleop.synthetic import SyntheticMotion, _both, _keyframes, motion_configurations
    from wbcbench.types import ActuationMode

    behind, up = _both({"right_shoulder_Z": -80.0, "right_elbow_Z": 20.0}), _both({"right_shoulder_Z": 160.0,
                                                                                  "right_shoulder_X": 30.0})
    frames = [(0.3, {}), (0.6, behind), (0.9, up), (1.2, _both({"right_shoulder_Z": -80.0})),
              (1.5, _both({"right_shoulder_Z": 160.0})), (1.8, {})]
    motion = SyntheticMotion("swing_back", "arms swung behind the back and overhead", "A", 2.5, 50.0,
                             lambda t: _keyframes(t, frames))
    human, _, qs = motion_configurations(motion)
    path = write_bvh(tmp_path / "swing_back.bvh", human.bvh_skeleton(0.01), human.bvh_motion(qs, 0.01), 1 / 50.0)
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
    np.testing.assert_array_equal(params, P)
    off = TSIDTeleop(talos, ActuationMode.SPD, 1e-3, reach_cap=False)
    assert not off.reach_cap and off.formulation.acceleration_caps is None
    data = yaml.safe_load(taskset_path(talos, "teleop").read_text())
    for change, key in (({"tasks": ["left_hand", "left_wrist"]}, r"reach_cap\.tasks\[1\]"),
                        ({"error": [0.15, 0.10]}, r"reach_cap\.error"), ({"linear": 0.0}, r"reach_cap\.linear")):
        bad = tmp_path / "teleop.yaml"
        bad.write_text(yaml.safe_dump({**data, "reach_cap": {**data["reach_cap"], **change}}))
        with pytest.raises(ConfigError, match=key) as exc:
            load_taskset(bad, talos)
        assert "teleop.yaml" in str(exc.value) and "\n" not in str(exc.value)
