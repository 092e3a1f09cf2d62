"""Uneven terrain in simulation: stairs and tilted platforms (shortened), planner errors before running."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from wbcbench.runner import run
from wbcbench.side import Side

SCEN = Path(__file__).parents[1] / "wbcbench" / "scenarios"


def _final_soles(robot, log):
    q = np.column_stack([log[c] for c in log if c.startswith("q.")])[-1]
    d = robot.model.createData()
    pin.framesForwardKinematics(robot.model, d, q)
    return {s: d.oMf[robot.sole_frame_id(s)] for s in Side}


@pytest.mark.parametrize("controller", ["tsid-torque", "tsid-position", "ik"])
def test_climbs_the_first_stairs(talos, tmp_path, controller):
    """The stairs' plan at `com_height: 0.84`: at the standing height the leg-reach bound dipped the planned CoM
    3.5 cm in each double support and raised it 12 cm in the 0.4 s after lift-off (up to 3.1 m/s^2); the position
    schemes overshot that rise, the feet's normal force fell to 124 N (IK) and 266 N (TSID position) on this run,
    and the ZMP x error peaked at 0.15 / 0.12 m (the ZMP divides by g + c_z'')."""
    res = run("stairs-quick", controller, talos, out=tmp_path)
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    assert s["metrics"]["final_position_error_m"] < 0.05
    # both feet end on the second tread (20 cm up)
    for side, M in _final_soles(talos, res.log).items():
        assert M.translation[2] == pytest.approx(0.20, abs=0.01), side
    log = res.log
    t = log["t"]
    both = (log["in_contact_ref_left"] > 0.5) & (log["in_contact_ref_right"] > 0.5)
    z = log["com_ref.z"]
    starts = np.flatnonzero(np.diff(both.astype(int)) == 1) + 1
    ends = np.r_[np.flatnonzero(np.diff(both.astype(int)) == -1) + 1, len(t)]
    for a in starts:  # the planned CoM dips less than 2 cm in each double support
        b = ends[ends > a][0]
        assert z[a] - z[a:b].min() < 0.02, t[a]
    fz = log["contact_left.fz"] + log["contact_right.fz"]
    assert fz[t > 0.2].min() > 0.35 * talos.mass * 9.81   # the robot never nearly leaves the treads
    assert s["metrics"]["zmp_error_m"]["x"]["peak"] < 0.12
    # the plan bounds the swinging legs too (max_swing_leg_extension): without it the CoM rose after lift-off faster
    # than the swinging foot and the swing knee straightened into its limit at the last step (0 rad, TSID torque's
    # ZMP x error peak 0.096 m on this run; now 0.51 rad and 0.018 m)
    for side in ("left", "right"):
        swinging = log[f"in_contact_ref_{side}"] < 0.5
        assert log[f"q.leg_{side}_4_joint"][swinging].min() > 0.2, side
    if controller == "tsid-torque":
        assert s["metrics"]["zmp_error_m"]["x"]["peak"] < 0.04
        assert s["metrics"]["zmp_error_m"]["x"]["std"] < 0.006       # the paper's stairs: 0.006
    # every controller takes its stairs task set (IK and TSID position: their stabilizer gains for the stairs)
    assert Path(json.loads((tmp_path / "config.json").read_text())["taskset_file"]).name == f"{controller}-stairs.yaml"


def test_torque_climbs_20cm_steps(talos, tmp_path):
    """Twice the paper's step height: the first two treads of stairs-20cm (the full scene also completes; with the
    plan's leg-reach bound, copies of it with 25, 27.5, 30 and 35 cm risers complete too and 40 cm falls on the
    third step; without the bound 25 cm fell)."""
    text = (SCEN / "stairs-20cm.yaml").read_text().replace("goal: [1.95, 0.0]", "goal: [0.75, 0.0]")
    assert "goal: [0.75, 0.0]" in text
    scen = tmp_path / "stairs-20cm-two.yaml"
    scen.write_text(text)
    res = run(str(scen), "tsid-torque", talos, out=tmp_path / "run")
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    assert s["metrics"]["final_position_error_m"] < 0.05
    for side, M in _final_soles(talos, res.log).items():  # both feet on the second tread, 40 cm up
        assert M.translation[2] == pytest.approx(0.40, abs=0.01), side


@pytest.mark.parametrize("controller", ["tsid-torque", "tsid-position", "ik"])
def test_crosses_all_the_tilted_platforms(talos, tmp_path, controller):
    """The full scene: six 15 deg platforms, every double support on two opposite slopes, then down to the floor.
    The position schemes needed four things (issue 6): no-slip contacts in this scene (the soft contacts let a
    loaded sole creep ~2 cm per step down a slope, which the integrated model never sees), the centroidal plan's
    leg-reach bound (the CoM kept 0.87 m above the upper foot asked the trailing leg for more than its length and
    the QP pitched the pelvis 27 deg back), the waist task on the pelvis (on the torso frame the pelvis was free to
    pitch), and the force-weighted CoM anchor (the single-foot one jumped when the load changed feet)."""
    res = run("platforms", controller, talos, out=tmp_path)
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    assert s["metrics"]["final_position_error_m"] < 0.15
    for side, M in _final_soles(talos, res.log).items():  # both feet on the floor past the last platform (x 1.95)
        assert M.translation[0] > 1.98 and abs(M.translation[2]) < 0.01, (side, M.translation)
    if controller != "tsid-torque":
        # base feedback with its lift-off blend: the real feet land on the plan (without base feedback IK ended
        # 10.7 cm off and its ZMP y mean error was 0.042 m, TSID position 4.8 cm and 0.028 m; with it but without the
        # blend the ZMP x peaks were 0.42 / 0.30 m)
        zmp = s["metrics"]["zmp_error_m"]
        assert s["metrics"]["final_position_error_m"] < 0.02
        assert zmp["y"]["mean"] < 0.025
        assert zmp["x"]["peak"] < 0.25
    if controller == "tsid-position":
        # the touch-down search at the downhill landings (without it, at the platforms' com_height 0.86: x mean
        # 0.034 m, two double supports with the leading foot unloaded), and the platforms' task set (kp_adm 16, base
        # feedback time constant 0.15 s, the leaving contact unloaded in the model before its lift-off; with
        # tsid-position.yaml x mean 0.024 m, without the unloading 0.0203 m, with it 0.0190 m); the plan lead (20 ms):
        # x / y mean 0.0190 / 0.0143 -> 0.0180 / 0.0128 m; the swing-foot tilt compensation: -> 0.0162 / 0.0119 m
        assert s["metrics"]["zmp_error_m"]["x"]["mean"] < 0.0170
        assert s["metrics"]["zmp_error_m"]["y"]["mean"] < 0.0125
        assert s["controller_status"]["touchdown_searches"] >= 3
    if controller == "ik":
        # the platforms' task set (kp_adm 20, kz_dcm 3; with ik.yaml 0.024 / 0.016 m): at or below the paper's Table 4;
        # with its plan lead (20 ms) x / y mean 0.0189 / 0.0128 -> 0.0174 / 0.0119 m
        assert zmp["x"]["mean"] <= 0.021 and zmp["y"]["mean"] <= 0.016
        assert zmp["x"]["mean"] < 0.0182 and zmp["y"]["mean"] < 0.0124
    if controller != "tsid-torque":
        taskset = Path(json.loads((tmp_path / "config.json").read_text())["taskset_file"]).name
        assert taskset == f"{controller}-platforms.yaml"


def _single_supports(log):
    ss = (log["in_contact_ref_left"] > 0.5) ^ (log["in_contact_ref_right"] > 0.5)
    d = np.diff(ss.astype(int))
    return list(zip(np.flatnonzero(d == 1) + 1, np.flatnonzero(d == -1) + 1))


def test_crosses_tilted_platforms_torque(talos, tmp_path):
    res = run("platforms-quick", "tsid-torque", talos, out=tmp_path)
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    assert s["metrics"]["final_position_error_m"] < 0.05
    # the feet end on the second platform, tilted with its 15 degree slope
    for side, M in _final_soles(talos, res.log).items():
        pitch = pin.rpy.matrixToRpy(M.rotation)[1]
        assert abs(abs(pitch) - np.radians(15)) < np.radians(2), (side, pitch)
    # `com_height: 0.86`: in the single support from the first platform's ridge to the second's slope the planned CoM
    # stays within 1 cm in height (0.4 cm; at the standing height the leg-reach bound moved it 1.9 cm)
    a, b = _single_supports(res.log)[2]
    z = res.log["com_ref.z"][a:b]
    assert z.max() - z.min() < 0.01


def test_tsid_position_searches_the_downhill_touch_down(talos, tmp_path):
    """platforms-quick, TSID position: the left foot lands on the second platform's falling slope 2-5 mm above it;
    its contact waits for the ankle F/T sensor's load (the touch-down search). Without the search the double support
    passed with that foot unloaded: ZMP x mean 0.040 m, peak 0.91 m on this run."""
    res = run("platforms-quick", "tsid-position", talos, out=tmp_path)
    s, log = res.summary, res.log
    assert not s["fell"], s["fall_reason"]
    assert s["controller_status"]["touchdown_searches"] >= 1
    planned, model = log["in_contact_ref_left"] > 0.5, log["contact_active.left"] > 0.5
    k = np.flatnonzero(planned[1:] & ~planned[:-1])[-1] + 1      # the left foot's landing on the slope
    made = k + np.flatnonzero(model[k:])[0]
    assert 10 <= made - k < 100                                     # the model's contact waits 10-100 ms
    assert -log["ft_left.fz"][made] >= 100.0                        # until the sensor reads the foot's load
    zmp = s["metrics"]["zmp_error_m"]["x"]
    assert zmp["mean"] < 0.025 and zmp["peak"] < 0.25


@pytest.mark.parametrize("old,new,needle", [
    ("goal: [1.95, 0.0]", "goal: [80.0, 0.0]", "off the terrain"),
    ("goal: [1.95, 0.0]", "goal: [9.0, 0.0]", "no reachable next surface"),
    ("height: 0.10,", "height: 0.40,", "no reachable"),
])
def test_planner_errors_before_simulation(tmp_path, old, new, needle):
    text = (SCEN / "stairs.yaml").read_text()
    assert old in text
    p = tmp_path / "scene.yaml"
    p.write_text(text.replace(old, new))
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "run", str(p), "-c", "tsid-torque", "-o", str(out)],
                          capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    line = proc.stderr.strip()
    assert "\n" not in line and "Traceback" not in line
    assert needle in line, line
    assert not (out / "log.parquet").exists()


def test_terrain_walk_com_height_sets_the_planned_height(talos, tmp_path):
    """`com_height` of a terrain walk: the centroidal plan starts at the standing CoM, carries the CoM at that height
    above the treads, and ends there on the second tread (20 cm up); without it, at the standing height."""
    from wbcbench.scenarios import load_scenario
    from wbcbench.sim.simulator import Simulator

    q = Simulator(talos).measure().q
    com0 = pin.centerOfMass(talos.model, talos.model.createData(), q)
    text = (SCEN / "stairs-quick.yaml").read_text()
    assert "  com_height: 0.84\n" in text
    low, default = tmp_path / "stairs-low.yaml", tmp_path / "stairs-default.yaml"
    low.write_text(text.replace("  com_height: 0.84", "  com_height: 0.80"))
    default.write_text(text.replace("  com_height: 0.84\n", ""))
    null = tmp_path / "stairs-null.yaml"   # null (a robot profile's way to undo the file's height): the standing one
    null.write_text(text.replace("  com_height: 0.84", "  com_height: null"))
    heights = {}
    for name, path in (("default", str(default)), ("low", str(low)), ("null", str(null))):
        scen = load_scenario(path, talos)
        scen.setup(q, com0)
        z = scen.walk.p_world_com[:, 2]
        assert z[0] == pytest.approx(com0[2], abs=1e-6)
        heights[name] = z[-1]
    d = talos.model.createData()
    pin.framesForwardKinematics(talos.model, d, q)
    ground = min(d.oMf[talos.sole_frame_id(s)].translation[2] for s in Side)
    assert heights["low"] == pytest.approx(ground + 0.20 + 0.80, abs=0.01)
    assert heights["default"] == pytest.approx(com0[2] + 0.20, abs=0.01)
    assert heights["null"] == heights["default"]


def test_taskset_variant_names_a_file_name(talos, tmp_path):
    """`taskset_variant` picks `<controller>-<variant>.yaml`; a name that cannot be part of a file name is refused
    with the file and the key."""
    from wbcbench.controllers.taskset import taskset_path, taskset_variant_path
    from wbcbench.errors import ConfigError
    from wbcbench.scenarios import load_scenario

    assert load_scenario("stairs", talos).spec.taskset_variant == "stairs"
    assert taskset_variant_path(talos, "tsid-torque", "stairs").name == "tsid-torque-stairs.yaml"
    assert taskset_variant_path(talos, "ik", "stairs").name == "ik-stairs.yaml"
    assert load_scenario("platforms", talos).spec.taskset_variant == "platforms"
    assert taskset_variant_path(talos, "tsid-torque", "platforms") is None  # TSID torque keeps its own task set there
    assert taskset_path(talos, "ik").name == "ik.yaml"
    text = (SCEN / "stairs-quick.yaml").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("taskset_variant: stairs", "taskset_variant: ../stairs"))
    with pytest.raises(ConfigError, match="taskset_variant") as err:
        load_scenario(str(bad), talos)
    assert "bad.yaml" in str(err.value)
