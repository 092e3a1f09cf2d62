"""Walking pattern generator on the paper's scenarios (Section 6): ZMP tracking, support polygon, rest at the
ends, consistent derivatives and DCM, contact schedule."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.planning import (
    ContactEventKind,
    PatternGeneratorConfig,
    Side,
    SoleRectangle,
    StepTiming,
    ZmpTransfer,
    generate_walk,
    lateral_walk,
    straight_walk,
    turning_walk,
    zmp_reference,
)

SOLE = SoleRectangle(0.20, 0.13)
SEP = 2 * 0.0857
COM_HEIGHT = 0.87
CONFIG = PatternGeneratorConfig(com_height=COM_HEIGHT)

SCENARIOS = {
    "walk_20cm": dict(n=6, length=0.20, ss=0.9, ds=0.115),
    "walk_20cm_fast": dict(n=6, length=0.20, ss=0.711, ds=0.089),
    "walk_60cm": dict(n=6, length=0.60, ss=0.9, ds=0.115),
}


def scenario_plan(name):
    s = SCENARIOS[name]
    return straight_walk(s["n"], s["length"], foot_separation=SEP, sole=SOLE,
                         timing=StepTiming(single_support=s["ss"], double_support=s["ds"]))


@pytest.fixture(scope="module")
def walks():
    return {name: generate_walk(scenario_plan(name), CONFIG) for name in SCENARIOS}


@pytest.fixture(scope="module")
def other_walks():
    timing = StepTiming(single_support=0.8, double_support=0.1)
    return {
        "lateral": generate_walk(lateral_walk(3, 0.08, foot_separation=SEP, sole=SOLE, timing=timing), CONFIG),
        "turning": generate_walk(turning_walk(4, 0.25, step_length=0.1, foot_separation=SEP, sole=SOLE,
                                              timing=timing), CONFIG),
        "stairs": generate_walk(straight_walk(4, 0.30, step_height=0.10, foot_separation=SEP, sole=SOLE,
                                              timing=timing), CONFIG),
    }


def support_margins(walk, points):
    """Signed margin [m] of points (n, 2+) in the support polygon of each tick (> 0 inside)."""
    left, right = walk.feet[Side.LEFT].in_contact, walk.feet[Side.RIGHT].in_contact
    state = left.astype(int) * 2 + right.astype(int)
    cuts = np.flatnonzero(np.diff(state)) + 1
    margins = np.empty(walk.n_ticks)
    for start, end in zip(np.r_[0, cuts], np.r_[cuts, walk.n_ticks]):
        poly = walk.support_polygon(start)
        edges = np.roll(poly, -1, axis=0) - poly
        inward = np.column_stack([-edges[:, 1], edges[:, 0]]) / np.linalg.norm(edges, axis=1)[:, None]
        d = np.einsum("nkj,kj->nk", points[start:end, None, :2] - poly[None], inward)
        margins[start:end] = d.min(axis=1)
    return margins


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_zmp_of_the_com_reproduces_the_plan(walks, name):
    w = walks[name]
    error = np.abs(w.p_world_zmp[:, :2] - w.p_world_zmp_ref[:, :2])
    # The whole walk, initial transient included: the hold keeps it at rest until the first ZMP move.
    assert error.max() < 1e-3, f"{name}: ZMP tracking error {error.max(axis=0)} m"
    # The ZMP is the cart-table output of the CoM: p = c - c_z / g c_ddot.
    np.testing.assert_allclose(w.p_world_zmp[:, :2],
                               w.p_world_com[:, :2] - COM_HEIGHT / 9.81 * w.a_world_com[:, :2], atol=1e-12)


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_zmp_inside_support_polygon_every_tick(walks, name):
    w = walks[name]
    ref_margin = support_margins(w, w.p_world_zmp_ref)
    com_margin = support_margins(w, w.p_world_zmp)
    assert ref_margin.min() > 0.05, f"{name}: planned ZMP margin {ref_margin.min()} m"
    assert com_margin.min() > 0.05, f"{name}: CoM ZMP margin {com_margin.min()} m"


@pytest.mark.parametrize("name", ["lateral", "turning", "stairs"])
def test_other_walks_track_and_stay_supported(other_walks, name):
    w = other_walks[name]
    assert np.abs(w.p_world_zmp[:, :2] - w.p_world_zmp_ref[:, :2]).max() < 1e-3
    assert support_margins(w, w.p_world_zmp).min() > 0.03
    assert support_margins(w, w.p_world_zmp_ref).min() > 0.03


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_final_com_between_final_feet_at_rest(walks, name):
    w = walks[name]
    final = w.plan.final_feet
    pl, pr = final[Side.LEFT].p_world_sole, final[Side.RIGHT].p_world_sole
    c = w.p_world_com[-1]
    mid = 0.5 * (pl + pr)
    assert pr[1] < c[1] < pl[1]
    assert np.linalg.norm(c[:2] - mid[:2]) < 1e-3
    assert c[2] == pytest.approx(COM_HEIGHT)
    assert np.linalg.norm(w.v_world_com[-1]) < 1e-3
    assert w.p_world_com[-1, 0] == pytest.approx(w.plan.steps[-1].p_world_sole[0], abs=1e-3)


def test_starts_exactly_at_rest(walks):
    w = walks["walk_20cm"]
    first_move = int(round((w.plan.timing.initial_double_support - CONFIG.initial_shift) / w.dt))
    horizon = int(round(CONFIG.preview_horizon / w.dt))
    assert first_move >= horizon  # the ZMP move is beyond the preview window at t = 0: no start-up spike
    rest = first_move - horizon  # the CoM starts moving when the move enters the preview window
    np.testing.assert_array_equal(w.p_world_com[:rest + 1, :2], 0.0)
    np.testing.assert_array_equal(w.v_world_com[:rest + 1], 0.0)
    np.testing.assert_array_equal(w.a_world_com[:rest + 1], 0.0)
    assert np.abs(w.a_world_com[rest + 1:rest + 100]).max() < 1e-4  # and then starts smoothly
    assert np.abs(w.p_world_zmp - w.p_world_zmp_ref)[:first_move].max() < 1e-3


def test_custom_initial_com_is_held():
    plan = scenario_plan("walk_20cm")
    w = generate_walk(plan, CONFIG, p_world_com_init=np.array([0.01, -0.005, 0.9]))
    np.testing.assert_allclose(w.p_world_com[0, :2], [0.01, -0.005])
    np.testing.assert_allclose(w.p_world_zmp_ref[0, :2], [0.01, -0.005])
    assert np.abs(w.v_world_com[:150]).max() == 0.0


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_derivatives_and_dcm_are_consistent(walks, name):
    w = walks[name]
    dt = w.dt
    # Piecewise-constant jerk: the velocity is the exact average slope plus a jerk term of order dt^2.
    np.testing.assert_allclose(np.diff(w.p_world_com, axis=0) / dt,
                               0.5 * (w.v_world_com[1:] + w.v_world_com[:-1]), atol=1e-5)
    np.testing.assert_allclose(np.diff(w.v_world_com, axis=0) / dt,
                               0.5 * (w.a_world_com[1:] + w.a_world_com[:-1]), atol=1e-6)
    # Eq. 2: xi = c + c_dot / omega and xi_dot = omega (xi - zmp).
    np.testing.assert_allclose(w.p_world_dcm, w.p_world_com + w.v_world_com / w.omega, atol=1e-12)
    xi_dot = np.diff(w.p_world_dcm[:, :2], axis=0) / dt
    mid = 0.5 * (w.p_world_dcm[1:, :2] - w.p_world_zmp[1:, :2] + w.p_world_dcm[:-1, :2] - w.p_world_zmp[:-1, :2])
    np.testing.assert_allclose(xi_dot, w.omega * mid, atol=1e-5)
    assert w.omega == pytest.approx(np.sqrt(9.81 / COM_HEIGHT))


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_feet_and_contact_schedule(walks, name):
    w = walks[name]
    plan = w.plan
    s = w.contacts
    assert len(s.events) == 2 * plan.n_steps
    lift_offs = [e for e in s.events if e.kind is ContactEventKind.LIFT_OFF]
    for i, e in enumerate(lift_offs):
        assert e.step == i and e.side is plan.steps[i].side
        assert e.tick == round(plan.lift_off_time(i) / w.dt)
        assert e.time == pytest.approx(plan.lift_off_time(i), abs=w.dt)
    # Never both feet in the air; single support lasts single_support.
    left, right = s.in_contact[Side.LEFT], s.in_contact[Side.RIGHT]
    assert np.all(left | right)
    assert (~left).sum() + (~right).sum() == plan.n_steps * round(plan.timing.single_support / w.dt)
    assert s.double_support.sum() == w.n_ticks - plan.n_steps * round(plan.timing.single_support / w.dt)
    for side, foot in w.feet.items():
        # A foot on the ground does not move.
        c = foot.in_contact
        assert np.abs(foot.v_world_sole[c]).max() == 0.0
        assert np.abs(foot.a_world_sole[c]).max() == 0.0
        assert np.all(np.diff(foot.p_world_sole, axis=0)[c[1:] & c[:-1]] == 0.0)
        # Swings reach the apex and land on their footsteps.
        if (~c).any():
            assert foot.p_world_sole[:, 2].max() == pytest.approx(CONFIG.swing_apex_height, abs=1e-6)
        # Velocities are the derivatives of positions.
        np.testing.assert_allclose(np.diff(foot.p_world_sole, axis=0) / w.dt,
                                   0.5 * (foot.v_world_sole[1:] + foot.v_world_sole[:-1]), atol=2e-4)
    for i, step in enumerate(plan.steps):
        td = round(plan.touch_down_time(i) / w.dt)
        np.testing.assert_allclose(w.feet[step.side].p_world_sole[td], step.p_world_sole, atol=1e-12)
        assert s.swing_side(td - 1) is step.side and s.swing_side(td) is None


def test_coarse_preview_rate_agrees_with_1khz(walks):
    """A plan computed at 5 ms and evaluated exactly at 1 kHz matches the 1 kHz one: the 1 ms Riccati
    solution is accurate."""
    coarse = generate_walk(scenario_plan("walk_20cm"),
                           PatternGeneratorConfig(com_height=COM_HEIGHT, preview_dt=0.005))
    fine = walks["walk_20cm"]
    assert coarse.n_ticks == fine.n_ticks
    np.testing.assert_allclose(coarse.p_world_com, fine.p_world_com, atol=5e-5)
    np.testing.assert_allclose(coarse.v_world_com, fine.v_world_com, atol=5e-4)
    assert np.abs(coarse.p_world_zmp - coarse.p_world_zmp_ref)[:, :2].max() < 1e-3


def test_stairs_raise_the_com_smoothly(other_walks):
    w = other_walks["stairs"]
    z = w.p_world_com[:, 2]
    assert z[0] == pytest.approx(COM_HEIGHT)
    assert z[-1] == pytest.approx(COM_HEIGHT + 0.4)
    assert np.all(np.diff(z) >= -1e-12)
    assert np.abs(w.a_world_com[:, 2]).max() < 2.0
    np.testing.assert_allclose(np.diff(z) / w.dt, 0.5 * (w.v_world_com[1:, 2] + w.v_world_com[:-1, 2]), atol=1e-4)
    # The swing apex clears the higher stair.
    lifted = w.feet[Side.RIGHT]
    assert lifted.p_world_sole[:, 2].max() == pytest.approx(0.4 + CONFIG.swing_apex_height, abs=1e-6)


def test_lower_walking_height_is_reached_before_the_zmp_moves():
    """initial_com_height: the CoM starts at it and descends to com_height, smoothly and at rest in x-y, before the
    first ZMP move; from then on the walk is the one planned at com_height."""
    plan = scenario_plan("walk_60cm")
    low = PatternGeneratorConfig(com_height=0.76, initial_com_height=COM_HEIGHT)
    w = generate_walk(plan, low)
    ref = generate_walk(plan, PatternGeneratorConfig(com_height=0.76))
    z, vz = w.p_world_com[:, 2], w.v_world_com[:, 2]
    first_move = int(round((plan.timing.initial_double_support - low.initial_shift) / w.dt))
    assert z[0] == pytest.approx(COM_HEIGHT) and vz[0] == 0.0 and w.a_world_com[0, 2] == 0.0
    assert np.all(np.diff(z[:first_move + 1]) <= 1e-12)
    np.testing.assert_allclose(z[first_move:], 0.76, atol=1e-12)
    assert np.abs(w.a_world_com[:, 2]).max() < 0.5
    np.testing.assert_allclose(np.diff(z) / w.dt, 0.5 * (vz[1:] + vz[:-1]), atol=1e-4)
    np.testing.assert_allclose(np.diff(vz) / w.dt, 0.5 * (w.a_world_com[1:, 2] + w.a_world_com[:-1, 2]), atol=1e-3)
    # x-y, the ZMP and the feet are those of the walk planned at 0.76 m throughout
    np.testing.assert_array_equal(w.p_world_com[:, :2], ref.p_world_com[:, :2])
    np.testing.assert_array_equal(w.p_world_zmp, ref.p_world_zmp)
    np.testing.assert_array_equal(w.p_world_com[first_move:], ref.p_world_com[first_move:])
    assert w.omega == pytest.approx(np.sqrt(9.81 / 0.76))


def test_sampling_interface(walks):
    w = walks["walk_20cm"]
    s = w.at(4.2)
    assert s.tick == 4200 and s.t == pytest.approx(4.2)
    np.testing.assert_array_equal(s.p_world_com, w.p_world_com[4200])
    assert s.contact_sides() == w.contacts.contact_sides(4200)
    T = s.feet[Side.LEFT].T_world_sole
    np.testing.assert_array_equal(T[:3, 3], w.feet[Side.LEFT].p_world_sole[4200])
    assert w.at(w.duration + 10.0).tick == w.n_ticks - 1
    assert w.at(0.0004).tick == 0
    with pytest.raises(ValueError):
        w.at(-1.0)
    with pytest.raises(IndexError):
        w.sample(w.n_ticks)
    with pytest.raises(ValueError):
        w.p_world_com[0, 0] = 1.0  # read-only


def test_deterministic():
    a = generate_walk(scenario_plan("walk_20cm_fast"), CONFIG)
    b = generate_walk(scenario_plan("walk_20cm_fast"), CONFIG)
    np.testing.assert_array_equal(a.p_world_com, b.p_world_com)
    np.testing.assert_array_equal(a.feet[Side.RIGHT].R_world_sole, b.feet[Side.RIGHT].R_world_sole)


def test_linear_transfer_and_zmp_reference():
    plan = scenario_plan("walk_20cm")
    cfg = PatternGeneratorConfig(com_height=COM_HEIGHT, zmp_transfer=ZmpTransfer.LINEAR)
    ref = zmp_reference(plan, cfg)
    lo = round(plan.lift_off_time(1) / cfg.dt)
    td = round(plan.touch_down_time(0) / cfg.dt)
    # Linear move across the double support between step 0 and step 1.
    mid = (td + lo) // 2
    np.testing.assert_allclose(ref[mid, 1], 0.5 * (ref[td, 1] + ref[lo, 1]), atol=2e-3)
    # Single support: on the stance sole centre.
    stance = plan.stance_foot(0)
    np.testing.assert_allclose(ref[td - 1, :2], stance.p_world_sole[:2])


@pytest.mark.parametrize("timing, kwargs, match", [
    (StepTiming(0.9, 0.115, initial_double_support=1.0), {}, "initial_double_support .* must be at least"),
    (StepTiming(0.9, 0.115, final_double_support=0.5), {}, "final_shift"),
    (StepTiming(0.9, 0.0005), {}, "shorter than one tick"),
    (StepTiming(0.9, 0.115), {"preview_dt": 0.0025}, "integer multiple"),
])
def test_config_and_timing_validation(timing, kwargs, match):
    plan = straight_walk(2, 0.2, foot_separation=SEP, sole=SOLE, timing=timing)
    with pytest.raises(ValueError, match=match):
        generate_walk(plan, PatternGeneratorConfig(com_height=COM_HEIGHT, **kwargs))


@pytest.mark.parametrize("kwargs, match", [
    ({"com_height": 0.0}, "com_height"),
    ({"com_height": 0.87, "dt": -1e-3}, "dt"),
    ({"com_height": 0.87, "zmp_transfer": "cubic"}, "allowed: smooth, linear"),
    ({"com_height": 0.87, "swing_apex_phase": 0.0}, "swing_apex_phase"),
    ({"com_height": 0.76, "initial_com_height": -0.87}, "initial_com_height"),
])
def test_config_rejects_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        PatternGeneratorConfig(**kwargs)


def test_standing_plan_without_steps():
    plan = straight_walk(0, 0.2, foot_separation=SEP, sole=SOLE, timing=StepTiming(0.9, 0.1))
    w = generate_walk(plan, CONFIG, p_world_com_init=[0.02, 0.0])
    assert w.contacts.events == ()
    assert np.linalg.norm(w.p_world_com[-1, :2]) < 1e-3
