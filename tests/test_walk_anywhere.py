"""Walking anywhere: turning in place, an arc of a circle, side steps, backward steps and a velocity-command profile
(the quick variants of the walk-command scenarios), with each controller: no fall, the base ends within 5 cm of
the plan and within 2 deg of the planned heading."""

import numpy as np
import pytest

from wbcbench.runner import run

SCENARIOS = ["turn-90-quick", "turn-180-quick", "circle-quick", "side-step-1m-quick", "backward-1m-quick",
             "velocity-profile-quick"]


@pytest.mark.parametrize("controller", ["tsid-torque", "tsid-position", "ik"])
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_walk_command_scenarios(talos, tmp_path, scenario, controller):
    res = run(scenario, controller, talos, out=tmp_path)
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    m = s["metrics"]
    assert m["final_position_error_m"] < 0.05
    assert m["final_yaw_error_deg"] < 2.0
    # it stepped: every foot was lifted at least once, and it went where the plan goes
    for side in ("left", "right"):
        assert np.any(res.log[f"in_contact_ref_{side}"] == 0)
    assert abs(m["planned_turn_deg"]) > 15 or m["planned_distance_m"] > 0.25
    assert m["distance_m"] == pytest.approx(m["planned_distance_m"], abs=0.05)


def _run_cli(args):
    import subprocess
    import sys
    return subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", *args], capture_output=True, text=True)


@pytest.mark.parametrize("params,needle", [
    ("  path: [[0.0, 1.0]]\n", "params.path"),
    ("  path: [[0.0, 1.0, 0.0]]\n  command: [[0, 0.1, 0, 0], [1, 0.1, 0, 0]]\n", "exactly one of"),
    ("  command: [[1.0, 0.1, 0.0, 0.0], [2.0, 0.1, 0.0, 0.0]]\n", "start at 0"),
    ("  command_csv: missing.csv\n", "cannot read"),
])
def test_bad_commands_are_rejected_before_running(tmp_path, params, needle):
    p = tmp_path / "bad.yaml"
    p.write_text("name: bad\nkind: walk-command\nterrain: {type: flat}\nparams:\n" + params
                 + "  single_support: 0.8\n  double_support: 0.1\n")
    proc = _run_cli([str(p), "-c", "tsid-torque", "-o", str(tmp_path / "run")])
    assert proc.returncode == 2, proc.stderr
    line = proc.stderr.strip()
    assert "\n" not in line and "Traceback" not in line and str(p) in line and needle in line, line


def test_bad_stepping_limit_in_a_profile_is_rejected(tmp_path):
    from wbcbench.robots.profile import PROFILE_DIR
    text = (PROFILE_DIR / "talos.yaml").read_text()
    p = tmp_path / "talos.yaml"
    p.write_text(text.replace("  max_turn: 0.35", "  max_turn: -0.35"))
    proc = _run_cli(["stand", "-c", "joint-pd", "-r", str(p), "-o", str(tmp_path / "run"), "-d", "0.01"])
    assert proc.returncode == 2, proc.stderr
    line = proc.stderr.strip()
    assert "\n" not in line and "stepping" in line and "max_turn" in line, line


def test_base_feedback_keeps_ik_on_its_plan(talos, tmp_path):
    """IK with the task-set switch on: the drift it estimates is real (mm) and the side step ends on its plan."""
    from dataclasses import replace

    from wbcbench.controllers.ik import MAX_LEVELS, IKController
    from wbcbench.controllers.taskset import load_taskset, taskset_path
    from wbcbench.estimation.base_feedback import BaseFeedbackConfig
    from wbcbench.sim.model import ActuationMode

    spec = load_taskset(taskset_path(talos, "ik"), talos, max_level=MAX_LEVELS)
    ctrl = IKController(talos, ActuationMode.POSITION, 1e-3,
                        taskset=replace(spec, base_feedback=BaseFeedbackConfig(time_constant=1.0)))
    res = run("side-step-1m-quick", ctrl, talos, out=tmp_path)
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    assert 1e-3 < np.hypot(*ctrl.corrections.base_feedback.drift[:2]) < 0.1
    assert s["metrics"]["final_position_error_m"] < 0.01
