"""An operator who walks: with feet fixed the robot stands (the CoM reference inside the support); with stepping
(`locomotion: stepping`) the robot takes the operator's steps through the walking stack."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from wbcbench.planning.geometry import SoleRectangle, polygon_margin, support_polygon
from wbcbench.recorder import channel
from wbcbench.side import Side
from wbcbench.teleop import load_recording, read_bvh
from wbcbench.teleop.human.locomotion import detect_steps
from wbcbench.teleop.registry import recording_path
from wbcbench.teleop.session.commands import run_session
from wbcbench.teleop.skeleton_map import map_segments

DATA = Path(__file__).parents[1] / "data" / "teleop"
#: the corpus' walking clip: the operator walks 1.0 m forward in 2 s (tests/data/teleop/MANIFEST.yaml)
WALKING_CLIP = DATA / "cmu_60_15.bvh"


def _min_jerk(s):
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def short_steps(seconds: float = 3.0, length: float = 0.2, times=((0.5, 0.9), (1.2, 1.6), (1.9, 2.3))):
    """The shipped `reach_forward` recording (operator A) with the operator walking in short steps: the feet
    (ankle and toe segments) step forward in turn by `length` (right, left, then the right closing beside the
    left), lifted 8 cm on the way, the rest of the body carried by the feet's mean displacement."""
    rec = read_bvh(recording_path("reach_forward"))
    names = map_segments(rec.segments, rec.parents).names
    n = int(round(seconds * rec.frame_rate))
    t = np.asarray(rec.times[:n]) - rec.times[0]
    P = np.array(rec.positions[:n], dtype=float)
    up = np.array([0.0, 1.0, 0.0])  # the shipped recordings' suit world is y-up
    left = P[0, rec.segment_index(names["LeftUpperLeg"])] - P[0, rec.segment_index(names["RightUpperLeg"])]
    left -= (left @ up) * up
    fwd = np.cross(left / np.linalg.norm(left), up)
    plan = [("RightFoot", 0.0, length), ("LeftFoot", 0.0, 2 * length), ("RightFoot", length, 2 * length)]
    disp = {"LeftFoot": np.zeros((n, 3)), "RightFoot": np.zeros((n, 3))}
    for (foot, x0, x1), (ta, tb) in zip(plan, times):
        u = (t - ta) / (tb - ta)
        inside = (u > 0) & (u < 1)
        d = (x0 + _min_jerk(u) * (x1 - x0))[:, None] * fwd + (0.08 * np.sin(np.pi * u) * inside)[:, None] * up
        disp[foot] = np.where((t >= ta)[:, None], d, disp[foot])
    body = 0.5 * (disp["LeftFoot"] + disp["RightFoot"]) * np.array([1.0, 0.0, 1.0])  # horizontal only
    feet = {}
    for side in ("Left", "Right"):
        for seg in (f"{side}Foot", f"{side}Toe"):
            if names.get(seg) in rec.segments:
                feet[rec.segment_index(names[seg])] = disp[f"{side}Foot"]
    for j in range(len(rec.segments)):
        P[:, j] += feet.get(j, body)
    return dataclasses.replace(rec, times=rec.times[:n], positions=P, orientations=rec.orientations[:n],
                               joint_angles=rec.joint_angles[:n])


def test_steps_are_detected_on_the_walking_clip():
    rec = load_recording(WALKING_CLIP)
    names = map_segments(rec.segments, rec.parents).names
    steps = detect_steps(rec, names, rec.conventions["up"])
    assert [s.side for s in steps] == ["left", "right", "left"]
    for s in steps:
        d = s.p_suit - s.p_suit_before
        assert 0.3 < np.linalg.norm([d[0], d[2]]) < 0.9 and s.touch_down > s.lift_off


def test_feet_fixed_walking_clip_stands_over_its_support(talos, tmp_path):
    res = run_session(str(WALKING_CLIP), robot=talos, locomotion="feet_fixed", out=tmp_path / "run")
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    om = s["metrics"]["teleop"]["skeleton"]["operator_motion"]
    assert om["applied"] and om["travel_m"] > 0.8
    # the CoM reference stays inside the support polygon of the measured feet, with margin
    log = res.log
    q, com_ref = channel(log, "q"), channel(log, "com_ref")
    model, data = talos.model, talos.model.createData()
    sole = SoleRectangle(talos.profile.sole.length, talos.profile.sole.width, *talos.profile.sole.center)
    margins = []
    for k in range(0, len(q), 50):
        pin.framesForwardKinematics(model, data, q[k])
        feet = [data.oMf[talos.sole_frame_id(side)] for side in Side]
        poly = support_polygon([sole.footprint(M.translation, M.rotation) for M in feet])
        margins.append(polygon_margin(com_ref[k], poly))
    assert min(margins) > 0.02, min(margins)


@pytest.fixture(scope="module")
def short_walk(talos, tmp_path_factory):
    return run_session(short_steps(), robot=talos, locomotion="stepping", out=tmp_path_factory.mktemp("walk"))


def test_stepping_follows_the_operators_placements(short_walk):
    s = short_walk.summary
    assert not s["fell"], s["fall_reason"]
    st = s["metrics"]["teleop"]["stepping"]
    assert st["operator_steps"] == 3 and st["robot_steps_taken"] >= 2 and st["steps_reached"] == 3
    errors = [r["placement_error_m"] for r in st["steps"]]
    assert max(errors) < 0.10, st["steps"]
    # the robot walked: the left foot landed well ahead of where the right one had
    assert st["steps"][1]["measured"][0] - st["steps"][0]["measured"][0] > 0.1
    # the plan is causal: no placement used by the preview before the operator's foot was down
    assert st["look_ahead_s"] <= 0.0


def test_stepping_on_the_walking_clip_clamps_to_the_robots_limits(talos, tmp_path):
    """The corpus' walking operator steps 0.5-1.0 m (scaled): beyond TALOS' step limits (0.3 m forward); with
    `catch_up: 0` the robot's steps are clamped; it lands where it planned, and stands."""
    res = run_session(str(WALKING_CLIP), robot=talos, locomotion="stepping", stepping={"catch_up": 0},
                      out=tmp_path / "run")
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    st = s["metrics"]["teleop"]["stepping"]
    assert st["robot_steps_taken"] >= 2 and st["steps_reached"] >= 2 and st["extra_steps"] == 0
    assert st["tracking_error_m"]["max"] < 0.05, st["steps"]
    assert st["clamp_m"]["max"] > 0.2   # clamped
    for r in st["steps"]:
        assert r["placement_error_m"] <= r["clamp_m"] + 0.05
    assert s["metrics"].get("self_collisions", 0) == 0


#: a real slow walk (the Rehazenter dataset, tests/data/teleop/MANIFEST.yaml): the operator is caught mid-stride
REAL_WALK = DATA / "rehazenter_2014001_c1_01.c3d"


def test_a_real_walk_is_followed_step_for_step(talos, tmp_path):
    """The Rehazenter walk (0.4 m/s, three steps of 0.42-0.45 m scaled, longer than TALOS' 0.3 m): the steps are
    detected where the file's own gait events put them; the calibration in the stride faces the operator's hips
    (the feet's right-to-left direction points along the walk), so the placements lie along the robot's forward
    axis; the robot reaches each of the operator's scaled placements in more steps than the operator (catch-up),
    lands within 10 cm of each, and stands, with no self-collision."""
    clip = next(c for c in yaml.safe_load((DATA / "MANIFEST.yaml").read_text())["clips"] if c["file"] == REAL_WALK.name)
    rec = load_recording(REAL_WALK)
    names = map_segments(rec.segments, rec.parents).names
    steps = detect_steps(rec, names, rec.conventions["up"])
    strikes = clip["events"]["foot_strike"]
    assert [s.side for s in steps] == ["right", "left", "right"]
    for s in steps:  # each touch-down within 0.1 s of a foot strike the capture's own events give that foot
        assert min(abs(s.touch_down - e) for e in strikes[s.side]) < 0.1, (s.side, s.touch_down)
    res = run_session(str(REAL_WALK), robot=talos, locomotion="stepping", out=tmp_path / "run")
    s = res.summary
    assert not s["fell"], s["fall_reason"]
    assert s["metrics"].get("self_collisions", 0) == 0
    st = s["metrics"]["teleop"]["stepping"]
    assert st["operator_steps"] == 3 and st["steps_reached"] == 3
    assert st["robot_steps_taken"] > st["operator_steps"] and st["extra_steps"] > 0   # it needed more steps
    x = [r["target"][0] for r in st["steps"]]
    assert all(abs(r["target"][1]) < 0.25 for r in st["steps"]) and x == sorted(x) and x[-1] > 1.5, st["steps"]
    errors = [r["placement_error_m"] for r in st["steps"]]
    assert max(errors) < 0.10, st["steps"]


def test_bad_locomotion_is_one_line(one_line_exit_2, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "teleop", "-i", "waving", "--locomotion", "walk",
                           "--out", str(tmp_path / "x"), "--quiet"], capture_output=True, text=True)
    one_line_exit_2(proc, "--locomotion", "walk", "stepping")


def test_operator_steps_are_clamped_by_the_robots_limits(talos):
    """The plan alone: a long step is clamped to max_forward, a crossing step is kept on its side, two steps of one
    foot get a step of the other in between, and every lift-off waits for its operator step plus the latency."""
    from types import SimpleNamespace

    from wbcbench.planning import Footstep
    from wbcbench.teleop.human.locomotion import OperatorStep
    from wbcbench.teleop.session.stepping import SteppingConfig, plan_operator_steps

    lim = talos.profile.stepping
    sole = SoleRectangle(talos.profile.sole.length, talos.profile.sole.width, *talos.profile.sole.center)
    feet0 = {Side.LEFT: Footstep.from_xyz_yaw(Side.LEFT, 0.0, 0.085),
             Side.RIGHT: Footstep.from_xyz_yaw(Side.RIGHT, 0.0, -0.085)}
    ankle0 = {"left": np.array([0.0, 0.085, 0.1]), "right": np.array([0.0, -0.085, 0.1])}
    zero = np.zeros(3)

    def step(side, x, y, td):
        return OperatorStep(side, td - 0.4, td, np.array([x, y, 0.1]), zero, 0.0)

    steps = [step("right", 0.6, -0.085, 1.0),     # 0.6 m: beyond max_forward
             step("left", 0.45, -0.2, 1.5),       # across the right foot
             step("left", 0.45, 0.085, 2.0)]      # the left again
    cfg = SteppingConfig(catch_up=0)
    sp = plan_operator_steps(steps, T_world_suit=SimpleNamespace(rotation=np.eye(3)), proportion=1.0,
                             feet_suit0=ankle0, feet0=feet0, limits=lim, sole=sole, config=cfg)
    plan = sp.plan
    assert plan.n_steps == 4 and sp.extra_steps == 1
    p0, p1, p3 = (np.array(r["planned"][:2]) for r in sp.placements)
    assert p0[0] == pytest.approx(lim.max_forward) and sp.placements[0]["clamp_m"] == pytest.approx(0.3)
    assert p1[1] - p0[1] >= sole.width + lim.min_clearance - 1e-9         # kept on its side of the right foot
    assert [s.side for s in plan.steps] == [Side.RIGHT, Side.LEFT, Side.RIGHT, Side.LEFT]
    assert np.allclose(p3, [0.45, 0.085]) and sp.placements[2]["clamp_m"] < 1e-9    # within the limits: exact
    assert plan.steps[2].p_world_sole[0] == pytest.approx(0.6)   # the extra step: the right foot to its target
    for i, r in enumerate(sp.placements):
        assert plan.lift_off_time(r["robot_step"]) >= r["operator_touch_down_s"] + cfg.effective_latency - 1e-9
    assert sp.look_ahead <= 1e-9
    # with catch-up the 0.6 m step is reached: the left foot steps past the right one, then the right again
    sp = plan_operator_steps(steps[:1], T_world_suit=SimpleNamespace(rotation=np.eye(3)), proportion=1.0,
                             feet_suit0=ankle0, feet0=feet0, limits=lim, sole=sole, config=SteppingConfig())
    assert [s.side for s in sp.plan.steps] == [Side.RIGHT, Side.LEFT, Side.RIGHT] and sp.extra_steps == 2
    assert np.allclose(sp.placements[0]["planned"][:2], [0.6, -0.085]) and sp.placements[0]["clamp_m"] < 1e-9
    assert sp.placements[0]["robot_step"] == 2
    for a, b in zip(sp.plan.steps, sp.plan.steps[1:]):   # every step within the limits from the one before
        assert b.p_world_sole[0] - a.p_world_sole[0] <= lim.max_forward + 1e-9


def test_step_adjustment_keeps_a_pushed_stepping_robot_up(talos, tmp_path):
    """`stepping: {step_adjustment: true}`: a 300 N, 0.1 s sideways push in the first single support (without the
    step adjustment the robot fell 2.3 s later, measured once); the walk's DCM step adjustment re-plans the steps
    and the robot stands."""
    from wbcbench.controllers.taskset import load_taskset, taskset_path
    from wbcbench.controllers.teleop import TSIDTeleop
    from wbcbench.runner import run
    from wbcbench.scenarios.teleop_kind import TeleopScenario
    from wbcbench.scene import Push
    from wbcbench.sim.model import ActuationMode

    scen = TeleopScenario.from_source(talos, short_steps(), locomotion="stepping", stepping={"step_adjustment": True})
    scen.spec = dataclasses.replace(scen.spec, pushes=(Push("base_link", (0.0, 300.0, 0.0), 3.1, 0.1),))
    ctrl = TSIDTeleop(talos, ActuationMode.POSITION, scen.spec.control_dt,
                      taskset=load_taskset(taskset_path(talos, "teleop-stepping"), talos))
    s = run(scen, ctrl, robot=talos, out=tmp_path / "run").summary
    assert not s["fell"], s["fall_reason"]
    assert s["metrics"]["teleop"]["stepping"]["step_adjustments"] > 0
