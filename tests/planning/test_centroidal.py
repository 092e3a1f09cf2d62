"""Centroidal QP and multi-contact walks: dynamics consistency, friction cones, swing clearance, references."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from wbcbench.planning import (
    CentroidalConfig,
    CentroidalPlanError,
    LegReach,
    ContactTerrain,
    Footstep,
    Side,
    SoleRectangle,
    StepTiming,
    WalkTrajectory,
    contacts_from_placements,
    generate_multicontact_walk,
    plan_centroidal,
    platform_boxes,
    stairs_boxes,
    terrain_walk,
)
from wbcbench.planning.geometry import polygon_margin

SOLE = SoleRectangle(0.20, 0.13)
TIMING = StepTiming(single_support=1.2, double_support=0.4, initial_double_support=1.5, final_double_support=2.0)
START = {Side.LEFT: Footstep.from_xyz_yaw(Side.LEFT, 0.0, 0.085),
         Side.RIGHT: Footstep.from_xyz_yaw(Side.RIGHT, 0.0, -0.085)}
MASS = 90.27
G = 9.81
MU = CentroidalConfig(mass=MASS).friction
CASES = {
    "stairs_10cm": (stairs_boxes(6, 0.10, 0.30), (1.95, 0.0)),
    "stairs_15cm": (stairs_boxes(6, 0.15, 0.30), (1.95, 0.0)),
    "platforms": (platform_boxes(), (2.1, 0.0)),
}


@functools.lru_cache(maxsize=None)
def _walk(name):
    boxes, goal = CASES[name]
    return terrain_walk(boxes, START, goal, timing=TIMING, sole=SOLE, mass=MASS, com_height=0.87)


@pytest.fixture(scope="module", params=sorted(CASES))
def walk(request):
    return _walk(request.param)


def test_walk_is_a_walk_trajectory(walk):
    w = walk.walk
    assert isinstance(w, WalkTrajectory)
    n = w.n_ticks
    assert n == int(round(walk.contacts.footsteps.duration / 1e-3)) + 1
    for name in ("p_world_com", "v_world_com", "a_world_com", "p_world_zmp_ref", "p_world_zmp", "p_world_dcm"):
        assert getattr(w, name).shape == (n, 3)
    assert w.omega == pytest.approx(np.sqrt(G / 0.87))
    sample = w.at(5.0)
    assert sample.p_world_com.shape == (3,) and set(sample.feet) == {Side.LEFT, Side.RIGHT}
    # feet in contact stand exactly on their footholds, at rest; swing feet are continuous
    feet = dict(START)
    for i, step in enumerate(w.plan.steps):
        td = int(round(w.plan.touch_down_time(i) / w.dt))
        np.testing.assert_allclose(w.feet[step.side].p_world_sole[td], step.p_world_sole, atol=1e-12)
    for s in Side:
        f = w.feet[s]
        np.testing.assert_allclose(f.v_world_sole[f.in_contact], 0.0, atol=1e-9)
        assert np.abs(np.diff(f.p_world_sole, axis=0)).max() < 0.01   # < 10 m/s, no jumps
        np.testing.assert_array_equal(f.in_contact, walk.centroidal.wrenches[s].in_contact)
    # DCM and its definition
    np.testing.assert_allclose(w.p_world_dcm, w.p_world_com + w.v_world_com / w.omega, atol=1e-12)
    # starts and ends at rest, the CoM over the feet at the end
    for k in (0, -1):
        np.testing.assert_allclose(w.v_world_com[k], 0.0, atol=1e-6)
        np.testing.assert_allclose(w.a_world_com[k], 0.0, atol=1e-6)
    final = w.plan.final_feet
    mid = 0.5 * (final[Side.LEFT].p_world_sole + final[Side.RIGHT].p_world_sole)
    np.testing.assert_allclose(w.p_world_com[-1, :2], mid[:2], atol=1e-6)


def test_dynamics_consistent_at_every_tick(walk):
    """m c_ddot = sum f + m g at every tick, and c, c_dot, c_ddot consistent with each other."""
    c = walk.centroidal
    residual = MASS * c.a_world_com - c.total_force() - MASS * np.array([0.0, 0.0, -G])
    assert np.abs(residual).max() < 1e-6 * MASS * G
    dt = c.dt
    fd_v = (c.p_world_com[2:] - c.p_world_com[:-2]) / (2 * dt)
    fd_a = (c.v_world_com[2:] - c.v_world_com[:-2]) / (2 * dt)
    assert np.abs(fd_v - c.v_world_com[1:-1]).max() < 1e-5
    # the acceleration is piecewise linear: central differences are exact but at the knots (jerk steps)
    smooth = np.ones(c.n_ticks, bool)
    smooth[c.knot_ticks] = False
    assert np.abs(fd_a - c.a_world_com[1:-1])[smooth[1:-1]].max() < 1e-6
    assert np.abs(fd_a - c.a_world_com[1:-1]).max() < 0.01
    assert c.report.max_equality_residual < 1e-6
    # the walk's references are the centroidal plan's
    np.testing.assert_array_equal(walk.walk.a_world_com, c.a_world_com)


def test_wrenches_inside_friction_cones_at_every_tick(walk):
    c = walk.centroidal
    cfg_margin = 0.02  # CentroidalConfig.cop_margin default
    for s in Side:
        w = c.wrenches[s]
        n = w.normal
        fn = np.einsum("nki,ni->nk", w.corner_forces, n)
        ft = np.linalg.norm(w.corner_forces - fn[..., None] * n[:, None, :], axis=-1)
        assert fn.min() >= -1e-6
        assert np.all(ft <= MU * fn + 1e-6)                          # every corner force in its cone
        Fn = np.einsum("ni,ni->n", w.force, n)
        Ft = np.linalg.norm(w.force - Fn[:, None] * n, axis=1)
        assert np.all(Ft <= MU * Fn + 1e-6)                          # the resultant too
        np.testing.assert_allclose(w.force[~w.in_contact], 0.0, atol=1e-9)   # no force in the air
        # centre of pressure inside the sole rectangle shrunk by the margin
        cop = w.cop(min_normal_force=1.0)
        loaded = ~np.isnan(cop[:, 0])
        assert loaded.sum() > 0.5 * len(cop)
        foot = walk.walk.feet[s]
        local = np.einsum("nji,nj->ni", foot.R_world_sole[loaded], cop[loaded] - foot.p_world_sole[loaded])
        assert np.abs(local[:, 2]).max() < 1e-9
        assert np.all(np.abs(local[:, 0]) <= SOLE.length / 2 - cfg_margin + 1e-7)
        assert np.all(np.abs(local[:, 1]) <= SOLE.width / 2 - cfg_margin + 1e-7)
    # the feet carry the weight at rest
    total = c.total_force()
    assert total[0, 2] == pytest.approx(MASS * G, rel=1e-6)


def test_zmp_and_angular_momentum(walk):
    """The wrench ZMP differs from the CoM ZMP exactly by the planned L_dot; L_dot stays small."""
    c = walk.centroidal
    denom = MASS * (c.a_world_com[:, 2] + G)
    dL = c.dL_world_com
    expected = c.p_world_zmp_com[:, :2] + np.column_stack([-dL[:, 1], dL[:, 0]]) / denom[:, None]
    np.testing.assert_allclose(c.p_world_zmp[:, :2], expected, atol=1e-9)
    assert np.abs(c.dL_world_com).max() / (MASS * G) < 0.01              # < 1 cm of ZMP shift
    assert c.report.am_linearization_error < 1e-4                       # converged linearisation
    assert np.abs(c.p_world_zmp - c.p_world_zmp_com)[:, :2].max() < 0.01
    # on coplanar horizontal supports the ZMP is on the support surface, inside the support polygon
    w = walk.walk
    checked = 0
    for k in range(0, w.n_ticks, 20):
        feet = [f for f in w.feet.values() if f.in_contact[k]]
        normals = np.array([f.R_world_sole[k][:, 2] for f in feet])
        heights = np.array([f.p_world_sole[k][2] for f in feet])
        if np.all(normals[:, 2] > 1 - 1e-12) and np.ptp(heights) < 1e-12:
            assert w.p_world_zmp_ref[k, 2] == pytest.approx(heights[0])
            assert polygon_margin(w.p_world_zmp_ref[k], w.support_polygon(k)) > -1e-6
            checked += 1
    if "platform" not in walk.contacts.surfaces[0].name:
        assert checked > 100


def test_swing_feet_never_penetrate_the_terrain(walk):
    """The sole box (0.20 x 0.13 x 0.02 m) at every tick of both feet, against every box and the floor."""
    terrain = walk.contacts.terrain
    w = walk.walk
    for s in Side:
        f = w.feet[s]
        depth = terrain.sole_penetration(f.p_world_sole, f.R_world_sole, SOLE, 0.02)
        assert depth.max() <= 1e-6, f"{s} foot penetrates by {depth.max():.4f} m at t = {np.argmax(depth) * w.dt} s"
    assert walk.max_swing_penetration <= 1e-6
    # the apex clears the higher foothold by the documented clearance (5 cm)
    for sw in walk.swings:
        z = sw.sample(np.linspace(sw.t_start, sw.t_end, 201)).p_world_sole[:, 2]
        assert z.max() >= max(sw.p_world_start[2], sw.p_world_end[2]) + 0.05 - 1e-9


def test_platform_walk_stands_on_opposite_slopes():
    mc = _walk("platforms")
    w, c = mc.walk, mc.centroidal
    nl = np.einsum("nij,j->ni", w.feet[Side.LEFT].R_world_sole, [0.0, 0.0, 1.0])
    nr = np.einsum("nij,j->ni", w.feet[Side.RIGHT].R_world_sole, [0.0, 0.0, 1.0])
    both = w.contacts.double_support
    fz = {s: c.wrenches[s].force[:, 2] for s in Side}
    loaded = (fz[Side.LEFT] > 0.2 * MASS * G) & (fz[Side.RIGHT] > 0.2 * MASS * G)
    steep = (nl[:, 2] <= np.cos(np.deg2rad(15.0)) + 1e-9) & (nr[:, 2] <= np.cos(np.deg2rad(15.0)) + 1e-9)
    opposite = both & loaded & steep & (nl[:, 0] * nr[:, 0] < 0.0)
    assert opposite.sum() * w.dt > 1.0   # more than a second in total, both feet loaded on opposite 15 deg slopes


def test_solvers_agree_on_a_short_plan():
    terrain = ContactTerrain.from_boxes(platform_boxes())
    plan = contacts_from_placements(terrain, START, [("right", 0.3, -0.085), ("left", 0.6, 0.085)],
                                    timing=StepTiming(0.8, 0.3, 0.6, 1.0), sole=SOLE).footsteps
    cfg = dict(mass=MASS, knot_dt=0.2, am_iterations=1, friction=0.7)
    a = plan_centroidal(plan, CentroidalConfig(solver="proxsuite", **cfg))
    b = plan_centroidal(plan, CentroidalConfig(solver="daqp", **cfg))
    np.testing.assert_allclose(a.p_world_com, b.p_world_com, atol=1e-6)
    for s in Side:
        np.testing.assert_allclose(a.wrenches[s].force, b.wrenches[s].force, atol=1e-3 * MASS * G)
    assert a.report.solver == "proxsuite" and b.report.solver == "daqp"


def test_infeasible_plans_raise():
    terrain = ContactTerrain.from_boxes(platform_boxes())
    # ending with both feet on a 15 deg slope needs mu >= tan(15 deg) = 0.27
    plan = contacts_from_placements(terrain, START, [("right", 0.3, -0.085), ("left", 0.6, 0.085),
                                                     ("right", 0.6, -0.085)],
                                    timing=StepTiming(0.8, 0.3, 0.6, 1.0), sole=SOLE).footsteps
    with pytest.raises(CentroidalPlanError, match="infeasible|INFEASIBLE"):
        plan_centroidal(plan, CentroidalConfig(mass=MASS, friction=0.2, knot_dt=0.2, am_iterations=0))
    with pytest.raises(CentroidalPlanError):
        plan_centroidal(plan, CentroidalConfig(mass=MASS, max_com_height=0.5, knot_dt=0.2, am_iterations=0))


def test_generate_from_a_bare_footstep_plan_needs_the_terrain():
    terrain = ContactTerrain.from_boxes(stairs_boxes())
    cp = contacts_from_placements(terrain, START, [("right", 0.18, -0.085), ("left", 0.18, 0.085)],
                                  timing=StepTiming(0.8, 0.3, 0.6, 1.0), sole=SOLE)
    with pytest.raises(ValueError, match="terrain"):
        generate_multicontact_walk(cp.footsteps, CentroidalConfig(mass=MASS))
    mc = generate_multicontact_walk(cp.footsteps, CentroidalConfig(mass=MASS, knot_dt=0.2), terrain=terrain)
    assert mc.contacts is None and len(mc.swings) == 2


def test_config_validation():
    with pytest.raises(ValueError, match="mass"):
        CentroidalConfig(mass=0.0)
    with pytest.raises(ValueError, match="solver"):
        CentroidalConfig(mass=MASS, solver="osqp")
    with pytest.raises(ValueError, match="am_iterations"):
        CentroidalConfig(mass=MASS, am_iterations=-1)
    assert CentroidalConfig(mass=MASS, com_height=0.9).max_com_height == pytest.approx(0.98)
    with pytest.raises(ValueError, match="cop_margin"):
        plan_centroidal(contacts_from_placements(ContactTerrain.from_boxes([]), START, [],
                                                 timing=TIMING, sole=SOLE).footsteps,
                        CentroidalConfig(mass=MASS, cop_margin=0.07))


# TALOS-like leg geometry: hip joint centre relative to the CoM (heading frame), ankle above the sole, and 94 % of
# the straight leg (0.705 m), the terrain-walk scenario's default
REACH = LegReach(hip_offset={Side.LEFT: [-0.017, 0.084, -0.128], Side.RIGHT: [-0.017, -0.084, -0.128]},
                 ankle_offset={Side.LEFT: [0.0, 0.0, 0.107], Side.RIGHT: [0.0, 0.0, 0.107]}, max_length=0.663)


def _hip_ankle_on_ground(mc, reach, swinging=False):
    """Largest hip-ankle distance [m] over the ticks where each foot is on the ground (pelvis upright), or with
    `swinging` where it is in the air."""
    w = mc.walk
    worst = 0.0
    for s in Side:
        ft = w.feet[s]
        on = w.contacts.in_contact[s] != swinging
        ankle = ft.p_world_sole[on] + np.einsum("nij,j->ni", ft.R_world_sole[on], reach.ankle_offset[s])
        yaw = np.arctan2(ft.R_world_sole[on, 1, 0], ft.R_world_sole[on, 0, 0])
        o = reach.hip_offset[s]
        hip = w.p_world_com[on] + np.stack([np.cos(yaw) * o[0] - np.sin(yaw) * o[1],
                                            np.sin(yaw) * o[0] + np.cos(yaw) * o[1], np.full(len(yaw), o[2])], 1)
        worst = max(worst, float(np.linalg.norm(hip - ankle, axis=1).max()))
    return worst


@pytest.mark.parametrize("name", ["stairs_10cm", "platforms"])
def test_leg_reach_bounds_the_com_height(name):
    """Without the bound the plan asks the trailing leg for more than its length on the stairs (the CoM stays
    0.87 m above the upper tread while the foot is still on the lower one); with it, every foot on the ground
    stays within reach (up to the linearisation about the previous solve and the cubic between knots)."""
    boxes, goal = CASES[name]
    free = _hip_ankle_on_ground(_walk(name), REACH)
    bounded = terrain_walk(boxes, START, goal, timing=TIMING, sole=SOLE, mass=MASS,
                           centroidal=CentroidalConfig(mass=MASS, com_height=0.87, leg_reach=REACH))
    got = _hip_ankle_on_ground(bounded, REACH)
    assert got <= REACH.max_length + 0.003, got
    assert free > REACH.max_length + (0.03 if name == "stairs_10cm" else 0.0), free
    # still a dynamically consistent plan
    w = bounded.walk
    forces = sum(bounded.centroidal.wrenches[s].force for s in Side)
    np.testing.assert_allclose(MASS * w.a_world_com, forces + MASS * np.array([0.0, 0.0, -G]), atol=1e-3 * MASS * G)


def test_leg_reach_bounds_the_swinging_legs():
    """Without `swing_max_length` the CoM rises after lift-off faster than the swinging foot: the plan asks the
    swinging leg for more than the stance bound (TALOS' stairs: 0.702 m of its 0.705 m straight leg at the last step,
    the swing knee ran into its limit); with it every knot inside a swing keeps the swinging leg within reach at
    the swing's planned pose (up to the linearisation and the cubic between knots)."""
    boxes, goal = CASES["stairs_10cm"]
    cfg = CentroidalConfig(mass=MASS, com_height=0.87, leg_reach=REACH)
    free = _hip_ankle_on_ground(terrain_walk(boxes, START, goal, timing=TIMING, sole=SOLE, mass=MASS, centroidal=cfg),
                                REACH, swinging=True)
    limit = 0.67
    reach = LegReach(REACH.hip_offset, REACH.ankle_offset, REACH.max_length, swing_max_length=limit)
    bounded = terrain_walk(boxes, START, goal, timing=TIMING, sole=SOLE, mass=MASS,
                           centroidal=CentroidalConfig(mass=MASS, com_height=0.87, leg_reach=reach))
    got = _hip_ankle_on_ground(bounded, reach, swinging=True)
    assert free > limit + 0.01, free
    assert got <= limit + 0.003, got
    assert _hip_ankle_on_ground(bounded, reach) <= REACH.max_length + 0.003


def test_leg_reach_validation():
    with pytest.raises(ValueError, match="both sides"):
        LegReach(hip_offset={Side.LEFT: [0, 0, 0]}, ankle_offset=REACH.ankle_offset, max_length=0.6)
    with pytest.raises(ValueError, match="3 finite"):
        LegReach(hip_offset={Side.LEFT: [0, 0], Side.RIGHT: [0, 0, 0]}, ankle_offset=REACH.ankle_offset,
                 max_length=0.6)
    with pytest.raises(ValueError, match="max_length"):
        LegReach(hip_offset=REACH.hip_offset, ankle_offset=REACH.ankle_offset, max_length=0.0)
    with pytest.raises(ValueError, match="swing_max_length"):
        LegReach(hip_offset=REACH.hip_offset, ankle_offset=REACH.ankle_offset, max_length=0.6, swing_max_length=-1.0)
    with pytest.raises(ValueError, match="leg_reach"):
        CentroidalConfig(mass=MASS, leg_reach=0.6)


def test_a_plan_is_made_once_per_inputs(monkeypatch, tmp_path):
    """The same inputs give the plan made before (in this process, or by another one through the shared directory)
    without solving again, equal to the solve's; other inputs are solved."""
    from wbcbench.planning import centroidal

    solves = []
    solve = centroidal._plan_centroidal
    monkeypatch.setattr(centroidal, "_plan_centroidal", lambda *a: solves.append(1) or solve(*a))
    monkeypatch.setattr(centroidal, "_MEMO", {})
    monkeypatch.setenv(centroidal.PLAN_CACHE_ENV, str(tmp_path))
    terrain = ContactTerrain.from_boxes(platform_boxes())
    plan = contacts_from_placements(terrain, START, [("right", 0.3, -0.085), ("left", 0.6, 0.085)],
                                    timing=StepTiming(0.8, 0.3, 0.6, 1.0), sole=SOLE).footsteps
    cfg = CentroidalConfig(mass=MASS, knot_dt=0.2, am_iterations=1, friction=0.7, leg_reach=REACH)
    first = plan_centroidal(plan, cfg)
    again = plan_centroidal(plan, cfg)
    assert len(solves) == 1
    assert len(list(tmp_path.glob("*.pickle"))) == 1
    monkeypatch.setattr(centroidal, "_MEMO", {})  # another process: from the shared directory
    shared = plan_centroidal(plan, cfg)
    assert len(solves) == 1
    for other in (again, shared):
        assert other is not first
        for name in ("p_world_com", "v_world_com", "a_world_com", "p_world_zmp", "knot_ticks"):
            np.testing.assert_array_equal(getattr(other, name), getattr(first, name))
        for s in Side:
            np.testing.assert_array_equal(other.wrenches[s].force, first.wrenches[s].force)
    plan_centroidal(plan, cfg, p_world_com_init=first.p_world_com[0] + [0.01, 0.0, 0.0])
    assert len(solves) == 2
