"""Contact planner: footholds on the surfaces, limits, explicit placements, clear errors before any simulation."""

from __future__ import annotations

import time

import numpy as np
import pytest

from wbcbench.planning import (
    ContactPlannerConfig,
    ContactTerrain,
    Footstep,
    Side,
    SoleRectangle,
    StepTiming,
    contacts_from_placements,
    find_foothold,
    locate_foot,
    platform_boxes,
    plan_contacts,
    stairs_boxes,
)
from wbcbench.scene import Box

SOLE = SoleRectangle(0.20, 0.13)
TIMING = StepTiming(single_support=1.2, double_support=0.4, initial_double_support=1.5, final_double_support=2.0)
START = {Side.LEFT: Footstep.from_xyz_yaw(Side.LEFT, 0.0, 0.085),
         Side.RIGHT: Footstep.from_xyz_yaw(Side.RIGHT, 0.0, -0.085)}
CFG = ContactPlannerConfig()


def _check_plan(plan, cfg=CFG):
    """Every foothold: on its surface plane, sole z = surface normal, sole inside by the margin, sole box free,
    step limits respected; returns the feet after each step."""
    terrain = plan.terrain
    feet = dict(START)
    corners_local = SOLE.corners_in_sole()
    for i, (step, surf) in enumerate(zip(plan.footsteps.steps, plan.surfaces)):
        assert surf in terrain.surfaces
        p, R = step.p_world_sole, step.R_world_sole
        assert float(surf.distance_to_plane(p)) == pytest.approx(0.0, abs=1e-9)
        np.testing.assert_allclose(R[:, 2], surf.normal, atol=1e-9)
        # the whole rectangle inside the polygon, by the margin, measured independently in the surface frame
        corners = p + corners_local @ R.T
        local = (corners - surf.vertices[0]) @ surf.R_world_surface[:, :2]
        poly = surf.polygon
        for a, b in zip(poly, np.roll(poly, -1, axis=0)):
            e = b - a
            inward = np.array([-e[1], e[0]]) / np.linalg.norm(e)
            assert np.all((local - a) @ inward >= cfg.margin - 1e-9), f"step {i} outside {surf.name}"
        assert plan.margins[i] >= cfg.margin - 1e-9
        assert terrain.sole_penetration(p + 1e-4 * surf.normal, R, SOLE, cfg.sole_thickness) <= 1e-6
        stance = feet[step.side.other]
        d = p - stance.p_world_sole
        assert abs(d[0]) <= cfg.max_step_length + 1e-9          # heading is +x here
        assert cfg.min_width - 1e-9 <= step.side.sign * d[1] <= cfg.max_width + 1e-9
        assert abs(d[2]) <= cfg.max_step_height + 1e-9
        feet[step.side] = step
    return feet


def test_stairs_6_x_10cm():
    terrain = ContactTerrain.from_boxes(stairs_boxes(6, 0.10, 0.30))
    plan = plan_contacts(terrain, START, (1.95, 0.0), timing=TIMING, sole=SOLE)
    assert plan.method == "greedy-dfs"
    feet = _check_plan(plan)
    names = [s.name for s in plan.surfaces]
    assert names[-2:] == ["step_6", "step_6"]
    assert {f"step_{i}" for i in range(1, 7)} <= set(names)
    for s in Side:
        assert feet[s].p_world_sole[2] == pytest.approx(0.6)
    np.testing.assert_allclose(0.5 * (feet[Side.LEFT].p_world_sole[:2] + feet[Side.RIGHT].p_world_sole[:2]),
                               [1.95, 0.0], atol=1e-9)
    # the greedy choice trades progress for margin: feet at the tread centres, toe 2 cm off the first riser
    for step, surf in zip(plan.footsteps.steps, plan.surfaces):
        if surf.name != "floor":
            assert step.p_world_sole[0] == pytest.approx(surf.vertices[:, 0].mean(), abs=1e-9)
    assert plan.footsteps.steps[0].p_world_sole[0] == pytest.approx(0.3 - 0.1 - CFG.clearance)


def test_stairs_15cm():
    terrain = ContactTerrain.from_boxes(stairs_boxes(6, 0.15, 0.30))
    plan = plan_contacts(terrain, START, (1.95, 0.0), timing=TIMING, sole=SOLE)
    feet = _check_plan(plan)
    assert feet[Side.LEFT].p_world_sole[2] == pytest.approx(0.9)


def test_platforms_have_both_feet_on_opposite_slopes():
    terrain = ContactTerrain.from_boxes(platform_boxes())
    plan = plan_contacts(terrain, START, (2.1, 0.0), timing=TIMING, sole=SOLE)
    _check_plan(plan)
    assert {f"platform_{i}" for i in range(1, 7)} <= {s.name for s in plan.surfaces}
    opposite = 0
    for i in range(1, plan.n_steps + 1):
        surf = plan.surfaces_before(i)
        nl, nr = surf[Side.LEFT].normal, surf[Side.RIGHT].normal
        if nl[0] * nr[0] < 0.0 and min(nl[2], nr[2]) <= np.cos(np.deg2rad(15.0)) + 1e-9:
            opposite += 1
    assert opposite >= 4


def test_plan_is_deterministic_and_fast():
    terrain = ContactTerrain.from_boxes(platform_boxes())
    t0 = time.perf_counter()
    a = plan_contacts(terrain, START, (2.1, 0.0), timing=TIMING, sole=SOLE)
    assert time.perf_counter() - t0 < 5.0
    b = plan_contacts(terrain, START, (2.1, 0.0), timing=TIMING, sole=SOLE)
    for sa, sb in zip(a.footsteps.steps, b.footsteps.steps):
        np.testing.assert_array_equal(sa.p_world_sole, sb.p_world_sole)


def test_flat_goal_reached_in_straight_steps():
    terrain = ContactTerrain.from_boxes([])
    plan = plan_contacts(terrain, START, (1.2, 0.0), timing=TIMING, sole=SOLE)
    xs = [s.p_world_sole[0] for s in plan.footsteps.steps]
    np.testing.assert_allclose(xs, [0.3, 0.6, 0.9, 1.2, 1.2], atol=1e-9)
    assert plan.footsteps.steps[0].side is Side.RIGHT


def test_goal_off_the_terrain():
    terrain = ContactTerrain.from_boxes(stairs_boxes(), floor=False)
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="goal .* is off the terrain"):
        plan_contacts(terrain, {s: f.moved_to(f.p_world_sole + [0.45, 0, 0.1], f.R_world_sole)
                                for s, f in START.items()}, (3.0, 0.0), timing=TIMING, sole=SOLE)
    with pytest.raises(ValueError, match="off the terrain"):  # beside the stairs: the foot would hit their side
        plan_contacts(ContactTerrain.from_boxes(stairs_boxes()), START, (1.0, 0.56), timing=TIMING, sole=SOLE)
    assert time.perf_counter() - t0 < 2.0


@pytest.mark.parametrize("boxes, goal, floor, match", [
    # a platform 0.6 m beyond the end of the start platform, no floor: a gap
    ((Box((0.0, 0.0, -0.05), (0.6, 1.0, 0.1), name="start"), Box((1.5, 0.0, -0.05), (0.6, 1.0, 0.1), name="far")),
     (1.5, 0.0), False, r"no reachable next surface: .*'start'.*'far'"),
    # stairs of 25 cm: too high a step
    (stairs_boxes(6, 0.25, 0.30), (1.95, 0.0), True, r"no reachable next surface: .*'floor'.*'step_1'"),
    # a 1 m wall across the way, a low platform behind it
    ((Box((1.0, 0.0, 0.5), (0.6, 1.0, 1.0), name="wall"), Box((2.0, 0.0, 0.05), (0.6, 1.0, 0.1), name="goal")),
     (2.0, 0.0), True, r"no reachable next surface: .*'wall'"),
    # stairs going down past the top: a 0.6 m drop
    (stairs_boxes(), (3.0, 0.0), True, r"no reachable next surface: .*'step_6'"),
])
def test_unreachable_surfaces_are_reported_quickly(boxes, goal, floor, match):
    terrain = ContactTerrain.from_boxes(boxes, floor=floor)
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=match):
        plan_contacts(terrain, START, goal, timing=TIMING, sole=SOLE)
    assert time.perf_counter() - t0 < 2.0


def test_goal_behind_a_turn_and_start_off_surface():
    terrain = ContactTerrain.from_boxes(stairs_boxes())
    with pytest.raises(ValueError, match="does not turn"):
        plan_contacts(terrain, START, (0.0, 2.0), timing=TIMING, sole=SOLE)
    floating = {s: f.moved_to(f.p_world_sole + [0, 0, 0.05], f.R_world_sole) for s, f in START.items()}
    with pytest.raises(ValueError, match="not on any contact surface"):
        plan_contacts(terrain, floating, (1.95, 0.0), timing=TIMING, sole=SOLE)
    with pytest.raises(ValueError, match="goal must be"):
        plan_contacts(terrain, START, (1.0,), timing=TIMING, sole=SOLE)


def test_explicit_placements_step_to_gait():
    terrain = ContactTerrain.from_boxes(stairs_boxes())
    placements = [("right", 0.18, -0.085), ("left", 0.18, 0.085)]
    for k in range(1, 7):
        x = 0.3 * k + 0.15
        placements += [("right", x, -0.085), ("left", x, 0.085)]
    plan = contacts_from_placements(terrain, START, placements, timing=TIMING, sole=SOLE)
    assert plan.method == "explicit"
    _check_plan(plan)
    assert [s.name for s in plan.surfaces][-2:] == ["step_6", "step_6"]
    # Footsteps are checked as given
    again = contacts_from_placements(terrain, START, list(plan.footsteps.steps), timing=TIMING, sole=SOLE)
    assert [s.name for s in again.surfaces] == [s.name for s in plan.surfaces]


@pytest.mark.parametrize("placements, match", [
    ([("right", 0.35, -0.085)], r"placement 0 \(right foot at \(0.350, -0.085\)\): no contact surface"),  # on the edge
    ([("right", 0.18, -0.085), ("left", 0.75, 0.085)], "placement 1 .*beyond max_step_length"),
    ([("right", 0.18, -0.085), ("left", 0.45, 0.085)], "placement 1 .*above the stance foot, beyond max_step_height"),
    ([Footstep.from_xyz_yaw(Side.RIGHT, 0.45, -0.085, 0.12)], "placement 0: .*not on any contact surface"),
    ([("right", 0.2, -0.085)], "placement 0 .*no contact surface"),     # toe at the riser: within the clearance
    ([("middle", 0.2, 0.0)], "placement 0 must be"),
])
def test_explicit_placements_errors(placements, match):
    terrain = ContactTerrain.from_boxes(stairs_boxes())
    with pytest.raises(ValueError, match=match):
        contacts_from_placements(terrain, START, placements, timing=TIMING, sole=SOLE,
                                 config=ContactPlannerConfig(max_step_height=0.08))


def test_find_and_locate_footholds():
    terrain = ContactTerrain.from_boxes(platform_boxes())
    f = find_foothold(terrain, Side.LEFT, (0.6, 0.085), 0.0, SOLE)
    assert f.surface.name == "platform_2" and f.margin == pytest.approx(0.0553, abs=1e-4)
    assert locate_foot(terrain, f.footstep, SOLE) is f.surface
    assert find_foothold(terrain, Side.LEFT, (0.45, 0.085), 0.0, SOLE) is None   # on the ridge
    # on the floor before the first platform: the sole box must keep 2 cm from the ramp starting at x = 0.15
    assert find_foothold(terrain, Side.LEFT, (0.05, 0.085), 0.0, SOLE) is None
    assert find_foothold(terrain, Side.LEFT, (0.03, 0.085), 0.0, SOLE).surface.name == "floor"
    assert find_foothold(terrain, Side.LEFT, (0.03, 0.085), 0.0, SOLE, clearance=0.0).surface.name == "floor"
    assert find_foothold(terrain, Side.LEFT, (0.05, 0.085), 0.0, SOLE, clearance=0.0).surface.name == "floor"


def test_config_validation():
    with pytest.raises(ValueError, match="max_step_length"):
        ContactPlannerConfig(max_step_length=0.0)
    with pytest.raises(ValueError, match="min_width <= foot_separation"):
        ContactPlannerConfig(foot_separation=0.3)
    with pytest.raises(ValueError, match="unknown side"):
        ContactPlannerConfig(first_side="middle")
