"""Step adjustment in physics: a backward push in the middle of a single support of the 20 cm walk that TSID torque
does not survive on its plan, survived when the next foothold and step time are re-planned from the measured DCM;
the same for TSID position with its task set's own settings, and IK's backward push with the late descent of a swing
sent back; off by default (the walk's references do not change)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from wbcbench.robustness import phase_times
from wbcbench.runner import run
from wbcbench.scenarios import load_scenario
from wbcbench.sim.push import Push

# measured with `wbcbench robustness push walk-20cm --quick --directions 4 --phases ss-mid` (README, Step
# adjustment): backwards, tsid-torque survives 30 N s without adjustment and falls at 37.5; with it it survives
# 67.5 N s and falls at 75. 45 N s lies between, with a margin on both sides.
IMPULSE, DIRECTION = 45.0, 180.0


def _pushed(talos, adjust: bool, impulse: float = IMPULSE, after: float = 1.5):
    scen = load_scenario("walk-20cm-quick", talos)
    t = phase_times("walk-20cm-quick")["ss-mid"]
    a = math.radians(DIRECTION)
    f = impulse / 0.1
    push = Push(body="base", force=(f * math.cos(a), f * math.sin(a), 0.0), start=t, duration=0.1)
    scen.spec = replace(scen.spec, pushes=(push,), duration=t + after)
    if adjust:
        scen.enable_step_adjustment()
    return scen, t


def _stretched(talos, tmp_path, impulse: float, t_push: float):
    """walk-20cm-quick with its own `step_adjustment: {late_descent: 0.0}` (every re-planned swing's height the old
    profile stretched) and the push of `_pushed` (impulse [N s] in DIRECTION at t_push)."""
    yaml = tmp_path / "stretched.yaml"
    yaml.write_text(Path(load_scenario("walk-20cm-quick", talos).spec.file).read_text().replace(
        "  apex: 0.05", "  apex: 0.05\n  step_adjustment: {late_descent: 0.0}"))
    stretched = load_scenario(str(yaml), talos)
    a = math.radians(DIRECTION)
    f = impulse / 0.1
    stretched.spec = replace(stretched.spec, duration=t_push + 3.0, pushes=(
        Push(body="base", force=(f * math.cos(a), f * math.sin(a), 0.0), start=t_push, duration=0.1),))
    return stretched


def test_a_push_survived_only_with_step_adjustment(talos, tmp_path):
    scen, t_push = _pushed(talos, adjust=True)
    res = run(scen, "tsid-torque", talos, out=tmp_path / "on")
    assert not res.summary["fell"], res.summary["fall_reason"]
    adj = scen.adjuster
    assert adj.count >= 1 and res.summary["metrics"]["step_adjustments"] == adj.count
    t_first, step, sol = adj.history[0]
    assert t_push < t_first < t_push + 0.1           # it reacted during the push
    nominal = scen.adjuster.nominal.plan.steps[step].p_world_sole
    landed = scen.walk.plan.steps[step].p_world_sole
    assert landed[0] < nominal[0] - 0.05            # the next foothold moved backwards, with the push
    # the swing foot's reference went there, continuously (no jump over 1 cm in a tick)
    side = scen.walk.plan.steps[step].side.value
    ref = np.column_stack([res.log[f"foot_ref_{side}.{a}"] for a in "xy"])
    swinging = res.log[f"in_contact_ref_{side}"] == 0
    assert np.abs(np.diff(ref[swinging], axis=0)).max() < 0.01
    # the robot's CoM is back near the (re-planned) plan
    com = np.array([res.log[f"com.{a}"][-1] for a in "xy"])
    com_ref = np.array([res.log[f"com_ref.{a}"][-1] for a in "xy"])
    assert np.linalg.norm(com - com_ref) < 0.1
    assert "step_adjustment.active" in res.log

    scen_off, _ = _pushed(talos, adjust=False)
    off = run(scen_off, "tsid-torque", talos, out=tmp_path / "off")
    assert off.summary["fell"]
    assert "step_adjustment.active" not in off.log


# TSID position, the same push, `--quick --directions 4 --phases ss-mid`: without adjustment it survives 30 N s
# backwards, is off its plan at 37.5 and falls at 45 (1.6 s after the push); with it (the task set's threshold 5 cm,
# deadband 4 cm, re-plan from the DCM) it survived 45 N s and fell at 52.5; with its late descent too, 60 and 67.5.
POSITION_IMPULSE = 45.0


def test_a_position_scheme_survives_a_push_only_with_step_adjustment(talos, tmp_path):
    scen, _ = _pushed(talos, adjust=True, impulse=POSITION_IMPULSE, after=2.0)
    res = run(scen, "tsid-position", talos, out=tmp_path / "on")
    assert not res.summary["fell"], res.summary["fall_reason"]
    cfg = scen.step_adjustment    # the task set's settings, taken over by the scenario
    assert (cfg.threshold, cfg.deadband, cfg.replan_from) == (0.05, 0.04, "dcm")
    assert scen.adjuster.count >= 1
    active = res.log["step_adjustment.active"] > 0
    assert (res.log["step_adjustment.dcm_error"][active] > cfg.threshold).all()   # never inside the region

    scen_off, _ = _pushed(talos, adjust=False, impulse=POSITION_IMPULSE, after=2.0)
    off = run(scen_off, "tsid-position", talos, out=tmp_path / "off")
    assert off.summary["fell"]


# TSID position, the same push at 52.5 N s: with its task set's settings but the re-planned swing's height the old
# profile stretched (late_descent 0) it falls (the pushed step lands short and is dragged); with the task set's
# late_descent (0.4: the swing at the apex height until 40 % of its remaining time) it stands: `--quick
# --directions 4 --phases ss-mid --max-impulse 120 --iterations 4`, backwards 45 -> 60 N s.
LATE_DESCENT_IMPULSE = 52.5


def test_a_late_descent_of_the_replanned_swing_keeps_tsid_position_up(talos, tmp_path):
    scen, t_push = _pushed(talos, adjust=True, impulse=LATE_DESCENT_IMPULSE, after=3.0)
    res = run(scen, "tsid-position", talos, out=tmp_path / "late")
    assert scen.step_adjustment.late_descent == 0.4            # the task set's
    assert not res.summary["fell"], res.summary["fall_reason"]
    assert scen.adjuster.count >= 1

    stretched = _stretched(talos, tmp_path, LATE_DESCENT_IMPULSE, t_push)  # the scenario's setting wins
    assert stretched.step_adjustment is not None and stretched.step_adjustment.late_descent == 0.0
    off = run(stretched, "tsid-position", talos, out=tmp_path / "stretched")
    assert stretched.step_adjustment.late_descent == 0.0 and stretched.step_adjustment.deadband == 0.04
    assert off.summary["fell"]


# IK, backwards at 60 N s: with its task set's settings but every re-planned swing's height the old profile
# stretched (late_descent 0) it falls (the left foot, sent 17 cm behind the stance foot, lands short and is dragged
# back, loaded); with the task set's late descent of a swing sent back (0.6, `late_descent_back`) it stands:
# `--quick --directions 4 --phases ss-mid --max-impulse 120 --iterations 4`, backwards 45 -> 60 N s.
IK_BACK_IMPULSE = 60.0


def test_ik_survives_a_backward_push_with_the_late_descent_of_a_swing_sent_back(talos, tmp_path):
    scen, t_push = _pushed(talos, adjust=True, impulse=IK_BACK_IMPULSE, after=3.0)
    res = run(scen, "ik", talos, out=tmp_path / "late")
    cfg = scen.step_adjustment
    assert (cfg.late_descent, cfg.late_descent_back) == (0.6, True)              # the task set's
    assert not res.summary["fell"], res.summary["fall_reason"]
    step = scen.adjuster.history[0][1]
    assert scen.walk.plan.steps[step].p_world_sole[0] < scen.adjuster.nominal.plan.steps[step].p_world_sole[0] - 0.1

    stretched = _stretched(talos, tmp_path, IK_BACK_IMPULSE, t_push)
    off = run(stretched, "ik", talos, out=tmp_path / "stretched")
    assert stretched.step_adjustment.late_descent == 0.0 and stretched.step_adjustment.deadband == 0.01
    assert off.summary["fell"]


def test_a_task_set_sets_what_the_scenario_leaves(talos, tmp_path):
    from wbcbench.errors import ConfigError
    from wbcbench.controllers.taskset import load_taskset, taskset_path
    from wbcbench.scenarios import make_scenario

    spec = load_taskset(taskset_path(talos, "tsid-position"), talos)
    assert dict(spec.step_adjustment) == {"threshold": 0.05, "deadband": 0.04, "replan_from": "dcm",
                                          "late_descent": 0.4}
    assert dict(load_taskset(taskset_path(talos, "tsid-torque"), talos).step_adjustment) == {"min_single_support": 0.35}
    params = {"steps": 1, "step_length": 0.2, "single_support": 0.9, "double_support": 0.1,
              "step_adjustment": {"threshold": 0.07}}
    scen = make_scenario("walk", talos, params=params)
    scen.adopt_step_adjustment(dict(spec.step_adjustment))
    assert (scen.step_adjustment.threshold, scen.step_adjustment.deadband) == (0.07, 0.04)   # the scenario's wins
    off = make_scenario("walk", talos, params={k: v for k, v in params.items() if k != "step_adjustment"})
    off.adopt_step_adjustment(dict(spec.step_adjustment))
    assert off.step_adjustment is None                                                     # off stays off
    bad = tmp_path / "ts.yaml"
    bad.write_text(taskset_path(talos, "tsid-position").read_text().replace("deadband: 0.04", "deadband: 0.06"))
    with pytest.raises(ConfigError, match="deadband"):
        load_taskset(bad, talos)


def test_off_by_default_and_the_switch_is_validated(talos):
    from wbcbench.errors import ConfigError
    from wbcbench.scenarios import make_scenario

    assert load_scenario("walk-20cm-quick", talos).step_adjustment is None
    scen = make_scenario("walk", talos, params={"steps": 1, "step_length": 0.2, "single_support": 0.9,
                                                "double_support": 0.1, "step_adjustment": {"threshold": 0.03}})
    assert scen.step_adjustment.threshold == 0.03 and scen.step_adjustment.max_forward == 0.3   # profile limits
    off = make_scenario("walk", talos, params={"steps": 1, "step_length": 0.2, "single_support": 0.9,
                                               "double_support": 0.1, "step_adjustment": {"enabled": False}})
    assert off.step_adjustment is None
    with pytest.raises(ConfigError, match="step_adjustment.treshold"):
        make_scenario("walk", talos, params={"steps": 1, "step_length": 0.2, "single_support": 0.9,
                                             "double_support": 0.1, "step_adjustment": {"treshold": 0.03}})
    with pytest.raises(ConfigError, match="min_single_support"):
        make_scenario("walk", talos, params={"steps": 1, "step_length": 0.2, "single_support": 0.9,
                                             "double_support": 0.1,
                                             "step_adjustment": {"min_single_support": 2.0}})
    with pytest.raises(ConfigError, match="kind 'walk-command'"):
        load_scenario("turn-90-quick", talos).enable_step_adjustment()


def test_the_command_line_switch_refuses_other_kinds(tmp_path, capsys):
    from wbcbench.cli import main

    code = main(["run", "turn-90-quick", "-c", "tsid-torque", "--step-adjustment", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert "--step-adjustment" in err and "walk" in err and len(err.strip().splitlines()) == 1
