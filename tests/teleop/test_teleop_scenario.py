"""The `teleop` scenario kind without physics: references, engagement, feed-forward, loss handling, clamping,
YAML loading and bad input."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.errors import ConfigError
from wbcbench.robots import Side
from wbcbench.scenarios import load_scenario
from wbcbench.scenarios.teleop_kind import TeleopScenario, rotation_error
from wbcbench.teleop import open_recording, write_pose_csv

DT = 1e-3


def _setup(robot, mocap="reach_forward", **params):
    sc = TeleopScenario.from_source(robot, mocap, **params)
    q = robot.q0
    sc.setup(q, pin.centerOfMass(robot.model, robot.model.createData(), q))
    return sc


def test_references_name_the_table_i_tasks_and_hold_the_com(talos):
    sc = _setup(talos, duration=2.0)
    refs = sc.references(0.5)
    assert set(refs.targets) == {"left_hand", "right_hand", "head", "head_pitch", "head_yaw"}
    assert refs.targets["head"] is refs.targets["head_pitch"]
    assert refs.contacts == frozenset(Side)
    np.testing.assert_array_equal(refs.com.position, sc.com0)


def test_engagement_starts_on_the_robot_and_ends_on_the_operator(talos):
    sc = _setup(talos, duration=3.0, engage_time=1.0, anchor="absolute")
    start = sc.references(0.0).targets
    for k, M in sc.initial_poses.items():
        assert np.allclose(start[k].position, M.translation) and np.allclose(start[k].rotation, M.rotation)
    raw = sc.trajectory
    k = int(round(1.5 / DT))
    late = sc.references(1.5).targets["left_hand"]
    np.testing.assert_allclose(late.position, raw.position["left_hand"][k])
    # TALOS: the operator's hands along the body are 0.2-0.3 m from the robot's half-sitting grippers
    assert np.linalg.norm(raw.position["left_hand"][0] - start["left_hand"].position) > 0.2


def test_rest_anchor_puts_the_operator_at_rest_on_the_robot_at_rest_and_reaching_hands_absolutely(talos):
    rest = _setup(talos, engage_time=0.0)  # the default anchor
    absolute = _setup(talos, engage_time=0.0, anchor="absolute")
    assert rest.anchor == "rest"
    P, A = rest.trajectory.position, absolute.trajectory.position
    # calibration frame: the robot's own effector positions (0.2-0.3 m from the absolute overlay for the hands,
    # 6 cm below it for the head)
    for e in ("left_hand", "right_hand", "head"):
        np.testing.assert_allclose(P[e][0], rest.reference_poses[e].translation, atol=1e-9)
    assert np.linalg.norm(A["left_hand"][0] - P["left_hand"][0]) > 0.2
    assert A["head"][0][2] - P["head"][0][2] > 0.04
    # the right hand reaching forward (source 2.5-3.5 s) is farther than rest_blend[1] from its rest position:
    # overlaid absolutely; within rest_blend[0] the whole calibration shift (to the spline's rounding)
    k = int(round(3.0 / DT))
    assert np.linalg.norm(A["right_hand"][k] - A["right_hand"][0]) > rest.rest_blend[1]
    np.testing.assert_allclose(P["right_hand"][k], A["right_hand"][k], atol=1e-9)
    d = np.linalg.norm(A["right_hand"] - A["right_hand"][0], axis=1)
    shift = np.linalg.norm(P["right_hand"] - A["right_hand"], axis=1)
    full = np.linalg.norm(rest.offsets["right_hand"])
    assert full > 0.2
    np.testing.assert_allclose(shift[d < rest.rest_blend[0] - 0.01], full, atol=2e-3)
    assert np.all(shift <= full + 2e-3)
    # the orientations are the retargeter's whatever the anchor
    np.testing.assert_allclose(rest.trajectory.rotation["left_hand"], absolute.trajectory.rotation["left_hand"])


def test_offset_anchor_shifts_every_position_by_the_calibration_offset(talos):
    off = _setup(talos, engage_time=0.0, anchor="offset")
    absolute = _setup(talos, engage_time=0.0, anchor="absolute")
    k = int(round(3.0 / DT))
    for e in ("left_hand", "head"):
        np.testing.assert_allclose(off.trajectory.position[e][k] - absolute.trajectory.position[e][k],
                                   off.offsets[e], atol=1e-9)


def test_feedforward_matches_finite_differences_and_speed(talos):
    for speed in (1.0, 2.0):
        sc = _setup(talos, speed=speed, engage_time=0.0)
        tr = sc.trajectory
        k = int(round(1.2 / speed / DT))  # the right hand is moving at source time 1.2 s
        for e in ("right_hand", "head"):
            v_fd = (tr.position[e][k + 1] - tr.position[e][k - 1]) / (2 * DT)
            np.testing.assert_allclose(tr.velocity[e][k][:3], v_fd, atol=1e-3 * (1 + np.abs(v_fd).max()))
            w_fd = pin.log3(tr.rotation[e][k + 1] @ tr.rotation[e][k - 1].T) / (2 * DT)  # world axes
            np.testing.assert_allclose(tr.velocity[e][k][3:], w_fd, atol=1e-3 * (1 + np.abs(w_fd).max()))
        assert np.abs(tr.velocity["right_hand"][k]).max() > 0.05
    sc = _setup(talos, feedforward=False)
    assert not np.any(sc.trajectory.velocity["right_hand"])


def test_after_the_recording_the_last_targets_are_held_and_reported(talos):
    sc = _setup(talos, duration=13.0, engage_time=0.0)
    last = sc.references(11.99).targets["right_hand"]
    after = sc.references(12.5).targets["right_hand"]
    np.testing.assert_allclose(after.position, last.position, atol=1e-3)
    assert not np.any(after.velocity)
    assert sc.record_valid[-1] is False and sc.loss_events == 1


def test_on_loss_reference_returns_to_the_reference_posture(talos):
    sc = _setup(talos, duration=16.0, engage_time=0.0, on_loss="reference", return_time=1.0)
    for t in np.arange(11.0, 14.0, 0.01):
        refs = sc.references(float(t))
    for k, M in sc.reference_poses.items():
        np.testing.assert_allclose(refs.targets[k].position, M.translation, atol=1e-9)


def test_out_of_reach_targets_are_clamped_and_flagged(talos):
    # the operator's motion scaled 2.5 times about the feet: reaching hands go far out of the robot's reach
    sc = _setup(talos, duration=12.0, engage_time=0.0, proportion=2.5)
    shell = sc.retargeter.workspaces["right_hand"]
    p = sc.trajectory.position["right_hand"]
    assert np.linalg.norm(p - shell.center, axis=1).max() <= shell.r_max + 2e-3  # the spline between clamped frames
    for t in np.arange(0.0, 12.0, 0.05):
        sc.references(float(t))
    assert sc.clamped_ticks["right_hand"] > 0


def test_rotation_error_is_the_frobenius_norm():
    R = pin.rpy.rpyToMatrix(0.1, -0.2, 0.3)
    assert rotation_error(np.eye(3), np.eye(3)) == 0.0
    assert rotation_error(R, np.eye(3)) == pytest.approx(np.linalg.norm(np.eye(3) - R))
    angle = np.linalg.norm(pin.log3(R))
    assert rotation_error(R, np.eye(3)) == pytest.approx(2 * np.sqrt(2) * np.sin(angle / 2))


def test_yaml_scenario_resolves_the_mocap_next_to_it(talos, tmp_path):
    write_pose_csv(tmp_path / "take.csv", open_recording("waving"))
    (tmp_path / "s.yaml").write_text("kind: teleop\nparams: {mocap: take.csv, speed: 2.0}\n")
    sc = load_scenario(str(tmp_path / "s.yaml"), talos)
    assert sc.planned_duration == pytest.approx(6.0) and not sc.live


@pytest.mark.parametrize("params, match", [
    ({"mocap": "nope.bvh"}, "no such file"),
    ({"mocap": "take.xyz"}, "unknown recording format"),
    ({"mocap": "udp://localhost:notaport"}, "udp://HOST:PORT"),
    ({"mocap": "waving", "speed": 0}, "speed.*> 0"),
    ({"mocap": "waving", "proportion": "feet"}, "proportion"),
    ({"mocap": "waving", "on_loss": "stop"}, "on_loss"),
    ({"mocap": "waving", "targets": {"left_foot": ["x"]}}, "unknown effector"),
    ({"mocap": "waving", "colour": 1}, "unknown key"),
    ({"mocap": "waving", "anchor": "feet"}, "anchor"),
    ({"mocap": "waving", "rest_blend": [0.5, 0.1]}, "rest_blend"),
])
def test_bad_params_are_one_line_errors(talos, tmp_path, params, match):
    import yaml

    (tmp_path / "s.yaml").write_text(yaml.safe_dump({"kind": "teleop", "params": params}))
    with pytest.raises(ConfigError, match=match) as exc:
        load_scenario(str(tmp_path / "s.yaml"), talos)
    assert "\n" not in str(exc.value)


def test_corrupted_recording_is_one_line_error(talos, tmp_path):
    bad = tmp_path / "cut.bvh"
    text = (open_recording("waving").source and open(open_recording("waving").source).read())
    bad.write_text(text[: len(text) // 3])  # truncated mid-file
    with pytest.raises(ConfigError) as exc:
        TeleopScenario.from_source(talos, str(bad))
    assert "cut.bvh" in str(exc.value) and "\n" not in str(exc.value)


def test_live_stream_needs_a_duration(talos):
    sc = TeleopScenario.from_source(talos, "udp://127.0.0.1:0")
    try:
        with pytest.raises(ConfigError, match="duration"):
            sc.planned_duration
    finally:
        sc.source.close()


def test_report_recomputes_table_ii_from_the_log(tmp_path):
    """The hand/head targets handed to the controller are in log.parquet; `wbcbench report` recomputes the
    Table II statistics from the run directory alone and finds the run's own numbers."""
    import json
    import subprocess
    import sys

    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "teleop", "-i", "reach_forward", "--duration", "1.5",
                           "--quiet", "--out", str(out)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "report", str(out), "--out", str(tmp_path / "rep")],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    results = json.loads((tmp_path / "rep" / "results.json").read_text())
    (row,) = results["teleop"].values()
    for key in ("hand_position_error_m", "hand_rotation_error", "head_position_error_m", "hand_errors"):
        assert row[key] == summary["metrics"][key], key
    assert row["hand_position_error_m"]["max"] > 0.01
    assert "Table II statistics, recomputed from the logs" in (tmp_path / "rep" / "report.md").read_text()
