"""Footsteps from a velocity command or a path: limits, no crossing or collision, arrival."""

import numpy as np
import pytest

from wbcbench.planning import SoleRectangle, StepTiming
from wbcbench.planning.command import StepLimits, VelocityCommand, plan_from_command, plan_from_path
from wbcbench.planning.geometry import polygons_penetration
from wbcbench.side import Side

LIM = StepLimits(max_forward=0.3, max_backward=0.2, max_lateral=0.2, max_turn=0.35, min_clearance=0.02)
SOLE = SoleRectangle(0.2, 0.13)
KW = dict(foot_separation=0.1714, timing=StepTiming(0.8, 0.1, 2.5, 1.0), sole=SOLE, limits=LIM)


def _check_steps(plan, lim=LIM):
    feet = dict(plan.initial_feet)
    grown = SoleRectangle(SOLE.length + lim.min_clearance, SOLE.width + lim.min_clearance)
    for step in plan.steps:
        stance = feet[step.side.other]
        p, angle = step.in_frame_of(stance)
        assert step.side.sign * p[1] > 0.0                      # no crossing
        assert angle <= lim.max_turn + 1e-6
        assert polygons_penetration(grown.footprint(step.p_world_sole, step.R_world_sole),
                                    grown.footprint(stance.p_world_sole, stance.R_world_sole)) <= 1e-9
        feet[step.side] = step


def _final_frame(plan):
    f = plan.final_feet
    mid = (f[Side.LEFT].p_world_sole + f[Side.RIGHT].p_world_sole) / 2
    return mid, f[Side.LEFT].yaw, f[Side.RIGHT].yaw


@pytest.mark.parametrize("yaw", [np.pi / 2, np.pi, -np.pi / 2])
def test_turn_in_place_ends_turned_with_feet_together(yaw):
    plan = plan_from_path([[0.0, 0.0, yaw]], **KW)
    _check_steps(plan)
    mid, yl, yr = _final_frame(plan)
    assert np.linalg.norm(mid[:2]) < 2e-3
    for y in (yl, yr):
        assert abs(np.angle(np.exp(1j * (y - yaw)))) < 2e-3
    # the inside foot leads
    assert plan.steps[0].side is (Side.LEFT if yaw > 0 else Side.RIGHT)


@pytest.mark.parametrize("target,leading", [((0.0, 1.0), Side.LEFT), ((0.0, -0.5), Side.RIGHT), ((-1.0, 0.0), None)])
def test_side_and_backward_steps_respect_the_limits(target, leading):
    plan = plan_from_path([[*target, 0.0]], **KW)
    _check_steps(plan)
    mid, yl, yr = _final_frame(plan)
    assert np.allclose(mid[:2], target, atol=2e-3) and abs(yl) < 1e-9 and abs(yr) < 1e-9
    prev = dict(plan.initial_feet)
    for step in plan.steps:
        d = step.p_world_sole - prev[step.side].p_world_sole
        assert abs(d[1]) <= 2 * LIM.max_lateral + 1e-9 and -2 * LIM.max_backward - 1e-9 <= d[0]
        prev[step.side] = step
    if leading is not None:
        assert plan.steps[0].side is leading
        # the leading foot steps out, the trailing foot closes: never more than max_lateral + separation apart
        assert all(abs(s.in_frame_of(plan.feet_before(i)[s.side.other])[0][1]) <= 0.1714 + LIM.max_lateral + 1e-9
                   for i, s in enumerate(plan.steps))


def test_velocity_command_circle_comes_back_to_the_start():
    r, v = 0.6, 0.15
    cmd = VelocityCommand.from_rows([[0.0, v, 0.0, v / r], [2 * np.pi * r / v, v, 0.0, v / r]])
    plan = plan_from_command(cmd, **KW)
    _check_steps(plan)
    mid, yl, yr = _final_frame(plan)
    assert np.linalg.norm(mid[:2]) < 0.01
    assert abs(np.angle(np.exp(1j * yl))) < 0.01
    # it went round: the farthest foot is about a diameter away
    far = max(np.linalg.norm(s.p_world_sole[:2]) for s in plan.steps)
    assert 2 * r - 0.15 < far < 2 * r + 0.15


def test_velocity_command_is_integrated_in_the_walking_frame():
    cmd = VelocityCommand.from_rows([[0.0, 0.0, 0.0, 0.0], [1.0, 0.2, 0.0, 0.0], [3.0, 0.2, 0.0, 0.0],
                                     [4.0, 0.0, 0.0, 0.0]])
    pose = cmd.poses(np.array([4.0, 10.0]))
    assert pose[0] == pytest.approx([0.6, 0.0, 0.0], abs=1e-6)   # 0.1 + 0.4 + 0.1 m
    assert pose[1] == pytest.approx(pose[0])                    # zero after the end
    plan = plan_from_command(cmd, **KW)
    assert _final_frame(plan)[0][:2] == pytest.approx([0.6, 0.0], abs=2e-3)


def test_velocity_command_from_csv(tmp_path):
    p = tmp_path / "cmd.csv"
    p.write_text("t,vx,vy,yaw_rate\n0,0.1,0,0\n2,0.1,0,0\n")
    assert VelocityCommand.from_csv(p).poses(np.array([2.0]))[0] == pytest.approx([0.2, 0, 0], abs=1e-6)
    p.write_text("t,vx,vy\n0,0.1,0\n")
    with pytest.raises(ValueError, match="header"):
        VelocityCommand.from_csv(p)
    with pytest.raises(ValueError, match="start at 0"):
        VelocityCommand.from_rows([[1.0, 0, 0, 0], [2.0, 0, 0, 0]])
