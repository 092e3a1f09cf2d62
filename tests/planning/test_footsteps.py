"""Footstep plans: generators, timing queries and validation before anything runs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.planning import (
    Footstep,
    FootstepPlan,
    ReachLimits,
    Side,
    SoleRectangle,
    StepIncrement,
    StepTiming,
    footsteps_from_increments,
    lateral_walk,
    polygons_penetration,
    straight_walk,
    turning_walk,
)

SOLE = SoleRectangle(0.20, 0.13)
SEP = 2 * 0.0857
TIMING = StepTiming(single_support=0.9, double_support=0.115)


def test_side_enum():
    assert Side.LEFT.other is Side.RIGHT and Side.RIGHT.other is Side.LEFT
    assert Side.LEFT.sign == 1.0 and Side.RIGHT.sign == -1.0
    assert Side.parse("Left") is Side.LEFT and Side.parse(Side.RIGHT) is Side.RIGHT
    with pytest.raises(ValueError, match="allowed: left, right"):
        Side.parse("middle")


def test_straight_walk_paper_20cm():
    plan = straight_walk(6, 0.20, foot_separation=SEP, sole=SOLE, timing=TIMING)
    assert plan.n_steps == 7
    sides = [s.side for s in plan.steps]
    assert sides == [Side.RIGHT, Side.LEFT] * 3 + [Side.RIGHT]
    xs = [s.p_world_sole[0] for s in plan.steps]
    np.testing.assert_allclose(xs, [0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.2], atol=1e-12)
    for s in plan.steps:
        assert s.p_world_sole[1] == pytest.approx(s.side.sign * 0.0857)
    final = plan.final_feet
    assert final[Side.LEFT].p_world_sole[0] == pytest.approx(1.2)
    assert final[Side.RIGHT].p_world_sole[0] == pytest.approx(1.2)
    # Timing queries.
    assert plan.lift_off_time(0) == pytest.approx(TIMING.initial_double_support)
    assert plan.touch_down_time(0) == pytest.approx(TIMING.initial_double_support + 0.9)
    assert plan.lift_off_time(1) == pytest.approx(TIMING.initial_double_support + 0.9 + 0.115)
    assert plan.duration == pytest.approx(TIMING.initial_double_support + 7 * 0.9 + 6 * 0.115
                                          + TIMING.final_double_support)
    assert plan.stance_foot(0).side is Side.LEFT
    with pytest.raises(IndexError):
        plan.lift_off_time(7)


def test_straight_walk_60cm_and_stairs():
    plan = straight_walk(6, 0.60, foot_separation=SEP, sole=SOLE, timing=TIMING)
    assert plan.final_feet[Side.LEFT].p_world_sole[0] == pytest.approx(3.6)
    stairs = straight_walk(6, 0.30, step_height=0.10, foot_separation=SEP, sole=SOLE, timing=TIMING)
    np.testing.assert_allclose([s.p_world_sole[2] for s in stairs.steps], [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.6])


def test_lateral_walk_leading_foot_opens():
    plan = lateral_walk(3, 0.10, foot_separation=SEP, sole=SOLE, timing=TIMING)
    assert [s.side for s in plan.steps] == [Side.LEFT, Side.RIGHT] * 3
    ys = [s.p_world_sole[1] for s in plan.steps]
    np.testing.assert_allclose(ys, [0.1857, 0.0143, 0.2857, 0.1143, 0.3857, 0.2143], atol=1e-12)
    right = lateral_walk(2, -0.05, foot_separation=SEP, sole=SOLE, timing=TIMING)
    assert right.steps[0].side is Side.RIGHT
    with pytest.raises(ValueError, match="lateral_step"):
        lateral_walk(2, 0.0, foot_separation=SEP, sole=SOLE, timing=TIMING)


def test_turning_walk_rotates_both_feet():
    plan = turning_walk(4, 0.2, foot_separation=SEP, sole=SOLE, timing=TIMING)
    assert plan.steps[0].side is Side.LEFT
    final = plan.final_feet
    assert final[Side.LEFT].yaw == pytest.approx(0.8)
    assert final[Side.RIGHT].yaw == pytest.approx(0.8)
    # Turning in place: the walking frame stays at the origin, the feet on a circle of radius SEP / 2.
    for s in plan.steps:
        assert np.linalg.norm(s.p_world_sole[:2]) == pytest.approx(SEP / 2)


def test_start_pose_and_increments():
    plan = footsteps_from_increments([StepIncrement(dx=0.1, dyaw=0.2)], first_side=Side.LEFT,
                                     foot_separation=SEP, sole=SOLE, timing=TIMING, start=(1.0, 2.0, 0.5, np.pi / 2))
    np.testing.assert_allclose(plan.initial_feet[Side.LEFT].p_world_sole, [1.0 - SEP / 2, 2.0, 0.5], atol=1e-12)
    step = plan.steps[0]
    expected = [1.0 - SEP / 2 * np.cos(0.2), 2.1 - SEP / 2 * np.sin(0.2), 0.5]
    np.testing.assert_allclose(step.p_world_sole, expected, atol=1e-12)
    assert step.yaw == pytest.approx(np.pi / 2 + 0.2)


# ---- validation ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, match", [
    ({"single_support": 0.0, "double_support": 0.1}, "single_support must be a positive duration"),
    ({"single_support": 0.9, "double_support": -0.1}, "double_support must be a positive duration"),
    ({"single_support": 0.9, "double_support": 0.1, "initial_double_support": 0.0}, "initial_double_support"),
    ({"single_support": 0.9, "double_support": 0.1, "final_double_support": float("nan")}, "final_double_support"),
])
def test_timing_rejects_non_positive_durations(kwargs, match):
    with pytest.raises(ValueError, match=match):
        StepTiming(**kwargs)


def test_overlapping_initial_feet_rejected():
    with pytest.raises(ValueError, match="initial feet: the left footprint overlaps the right foot"):
        straight_walk(2, 0.2, foot_separation=0.10, sole=SOLE, timing=TIMING)


def test_overlapping_lateral_step_rejected():
    # A manual plan with the left foot landing on the right one.
    init = {Side.LEFT: Footstep.from_xyz_yaw(Side.LEFT, 0.0, 0.0857),
            Side.RIGHT: Footstep.from_xyz_yaw(Side.RIGHT, 0.0, -0.0857)}
    bad = Footstep.from_xyz_yaw(Side.LEFT, 0.05, -0.02)
    with pytest.raises(ValueError, match=r"step 0 \(left foot\): the left footprint overlaps the right foot"):
        FootstepPlan(init, (bad,), TIMING, SOLE)


def test_overlap_from_turning_too_much_rejected():
    with pytest.raises(ValueError, match="overlaps"):
        turning_walk(3, 0.55, foot_separation=SEP, sole=SOLE, timing=TIMING,
                     limits=ReachLimits(max_yaw=1.5))


@pytest.mark.parametrize("make, match", [
    (lambda: straight_walk(3, 0.70, foot_separation=SEP, sole=SOLE, timing=TIMING), "beyond max_length 0.65"),
    (lambda: straight_walk(3, 0.30, foot_separation=SEP, sole=SOLE, timing=TIMING,
                           limits=ReachLimits(max_length=0.25)), "beyond max_length 0.25"),
    (lambda: lateral_walk(2, 0.35, foot_separation=SEP, sole=SOLE, timing=TIMING), "beyond max_width 0.45"),
    (lambda: straight_walk(2, 0.3, step_height=0.3, foot_separation=SEP, sole=SOLE, timing=TIMING),
     "beyond max_height 0.25"),
    (lambda: turning_walk(2, 0.5, foot_separation=0.3, sole=SOLE, timing=TIMING,
                          limits=ReachLimits(max_yaw=0.3)), "beyond max_yaw 0.3"),
])
def test_steps_beyond_reach_rejected(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_crossing_feet_rejected():
    init = {Side.LEFT: Footstep.from_xyz_yaw(Side.LEFT, 0.0, 0.0857),
            Side.RIGHT: Footstep.from_xyz_yaw(Side.RIGHT, 0.0, -0.0857)}
    crossed = Footstep.from_xyz_yaw(Side.LEFT, 0.3, -0.2)
    with pytest.raises(ValueError, match="crosses over the right"):
        FootstepPlan(init, (crossed,), TIMING, SOLE)


def test_bad_inputs_rejected():
    with pytest.raises(ValueError, match="n_steps"):
        straight_walk(-1, 0.2, foot_separation=SEP, sole=SOLE, timing=TIMING)
    with pytest.raises(ValueError, match="foot_separation"):
        straight_walk(2, 0.2, foot_separation=0.0, sole=SOLE, timing=TIMING)
    with pytest.raises(ValueError, match="SoleRectangle.width"):
        SoleRectangle(0.2, -0.1)
    with pytest.raises(ValueError, match="not a rotation"):
        Footstep(Side.LEFT, np.zeros(3), 2 * np.eye(3))
    with pytest.raises(ValueError, match="must point up"):
        Footstep(Side.LEFT, np.zeros(3), np.diag([1.0, -1.0, -1.0]))
    with pytest.raises(ValueError, match="exactly the sides"):
        FootstepPlan({Side.LEFT: Footstep.from_xyz_yaw(Side.LEFT, 0, 0.1)}, (), TIMING, SOLE)


def test_footstep_is_read_only():
    f = Footstep.from_xyz_yaw(Side.LEFT, 0.1, 0.2, 0.0, 0.3)
    with pytest.raises(ValueError):
        f.p_world_sole[0] = 1.0
    np.testing.assert_allclose(f.T_world_sole[:3, 3], [0.1, 0.2, 0.0])
    assert f.yaw == pytest.approx(0.3)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(0, 8), length=st.floats(-0.3, 0.6), height=st.floats(-0.15, 0.15),
       yaw=st.floats(-0.3, 0.3), first=st.sampled_from([Side.LEFT, Side.RIGHT]))
def test_valid_random_walks_never_overlap(n, length, height, yaw, first):
    plan = footsteps_from_increments([StepIncrement(dx=length, dz=height, dyaw=yaw)] * n, first_side=first,
                                     foot_separation=SEP, sole=SOLE, timing=TIMING)
    for i in range(plan.n_steps):
        feet = plan.feet_before(i + 1)
        a, b = feet[Side.LEFT], feet[Side.RIGHT]
        assert polygons_penetration(SOLE.footprint(a.p_world_sole, a.R_world_sole),
                                    SOLE.footprint(b.p_world_sole, b.R_world_sole)) <= 1e-9


def test_side_interoperates_with_the_robot_side():
    robots = pytest.importorskip("wbcbench.robots")
    assert Side.parse(robots.Side.LEFT) is Side.LEFT
    assert {Side.LEFT: 1}[robots.Side.LEFT] == 1
    init = {robots.Side.LEFT: Footstep.from_xyz_yaw(robots.Side.LEFT, 0.0, 0.0857),
            robots.Side.RIGHT: Footstep.from_xyz_yaw(robots.Side.RIGHT, 0.0, -0.0857)}
    plan = FootstepPlan(init, (), TIMING, SOLE)
    assert plan.initial_feet[Side.LEFT].side is Side.LEFT


def test_planning_does_not_import_the_robot_model():
    import subprocess
    import sys

    code = ("import sys, wbcbench.planning, wbcbench.stabilizers; "
            "bad = [m for m in ('pinocchio', 'mujoco', 'wbcbench.robots') if m in sys.modules]; "
            "assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True)
