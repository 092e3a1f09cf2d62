"""DCM-based step adjustment: the QP moves the next foothold with the DCM error and within the stepping limits,
keeps the LIPM relation u + b = p + (xi - p) tau, and the re-planned walk is continuous and lands on the new
foothold; inside the threshold nothing changes."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.errors import PlanningError
from wbcbench.planning import PatternGeneratorConfig, SoleRectangle, StepTiming, generate_walk, straight_walk
from wbcbench.planning.step_adjustment import StepAdjuster, StepAdjustmentConfig, adjust_step
from wbcbench.side import Side

OMEGA = np.sqrt(9.81 / 0.87)
SEP, SOLE_W = 0.17, 0.13
# the stance (right) foot at the origin, the left foot swinging to a nominal 20 cm step, 0.45 s left of 0.9 s
STANCE = np.array([0.0, -SEP / 2])
U_NOM = np.array([0.20, SEP / 2])
T_NOM, ELAPSED = 0.45, 0.45
B_NOM = np.array([-0.05, -0.04])


def _planned_dcm() -> np.ndarray:
    """The DCM now that, with the nominal timing, ends the step exactly at u_nom + b_nom."""
    return STANCE + (U_NOM + B_NOM - STANCE) / np.exp(OMEGA * T_NOM)


def _solve(dcm, config=None, yaw=0.0, stance=STANCE, u_nom=U_NOM, swing=Side.LEFT):
    cfg = config or StepAdjustmentConfig()
    return adjust_step(dcm, stance, yaw, swing, u_nom, B_NOM, T_NOM, ELAPSED, OMEGA, SEP, SOLE_W, cfg)


@pytest.mark.parametrize("adapt", [True, False])
def test_no_error_keeps_the_nominal_step(adapt):
    sol = _solve(_planned_dcm(), StepAdjustmentConfig(adapt_timing=adapt))
    np.testing.assert_allclose(sol.p_world_foothold, U_NOM, atol=1e-6)
    np.testing.assert_allclose(sol.dcm_offset, B_NOM, atol=1e-6)
    assert sol.remaining_time == pytest.approx(T_NOM, abs=1e-6)


@pytest.mark.parametrize("adapt", [True, False])
def test_forward_error_gives_a_longer_step(adapt):
    sol = _solve(_planned_dcm() + [0.03, 0.0], StepAdjustmentConfig(adapt_timing=adapt))
    assert sol.p_world_foothold[0] > U_NOM[0] + 0.05
    # the LIPM relation holds: the DCM at touch-down is the foothold plus the offset
    xi_end = STANCE + (_planned_dcm() + [0.03, 0.0] - STANCE) * np.exp(OMEGA * sol.remaining_time)
    np.testing.assert_allclose(sol.p_world_foothold + sol.dcm_offset, xi_end, atol=1e-6)


def test_forward_error_shortens_the_step_when_timing_adapts():
    sol = _solve(_planned_dcm() + [0.05, 0.0])
    assert sol.remaining_time < T_NOM - 0.02
    fixed = _solve(_planned_dcm() + [0.05, 0.0], StepAdjustmentConfig(adapt_timing=False))
    assert fixed.remaining_time == pytest.approx(T_NOM)


def test_backward_and_lateral_errors():
    back = _solve(_planned_dcm() + [-0.03, 0.0])
    assert back.p_world_foothold[0] < U_NOM[0] - 0.05
    left = _solve(_planned_dcm() + [0.0, 0.02], StepAdjustmentConfig(adapt_timing=False))
    assert left.p_world_foothold[1] > U_NOM[1] + 0.03          # wider, outwards
    assert abs(left.p_world_foothold[0] - U_NOM[0]) < 1e-6


@pytest.mark.parametrize("adapt", [True, False])
def test_limits_hold_for_large_errors(adapt):
    cfg = StepAdjustmentConfig(adapt_timing=adapt)
    rng = np.random.default_rng(3)
    for _ in range(50):
        err = rng.uniform(-0.3, 0.3, 2)
        sol = _solve(_planned_dcm() + err, cfg)
        x, y = sol.foothold_local
        assert -cfg.max_backward - 1e-9 <= x <= cfg.max_forward + 1e-9
        assert SOLE_W + cfg.min_clearance - 1e-9 <= y <= SEP + cfg.max_lateral + 1e-9   # left of the stance foot
        if adapt:
            assert max(cfg.min_remaining, cfg.min_single_support - ELAPSED) - 1e-6 <= sol.remaining_time
            assert sol.remaining_time <= cfg.max_single_support - ELAPSED + 1e-6
    far_left = _solve(_planned_dcm() + [0.0, 0.3], cfg)
    assert far_left.foothold_local[1] == pytest.approx(SEP + cfg.max_lateral, abs=1e-7)
    far_right = _solve(_planned_dcm() + [0.0, -0.3], cfg)      # the left foot may not cross: stops at min width
    assert far_right.foothold_local[1] == pytest.approx(SOLE_W + cfg.min_clearance, abs=1e-7)


def test_the_stance_frame_turns_with_the_stance_foot():
    """The same problem turned by 90 deg gives the turned answer (limits are in the stance sole frame)."""
    R = np.array([[0.0, -1.0], [1.0, 0.0]])
    err = np.array([0.25, 0.1])
    a = _solve(_planned_dcm() + err)
    b = adjust_step(R @ (_planned_dcm() + err), R @ STANCE, np.pi / 2, Side.LEFT, R @ U_NOM, R @ B_NOM, T_NOM,
                    ELAPSED, OMEGA, SEP, SOLE_W, StepAdjustmentConfig())
    np.testing.assert_allclose(b.p_world_foothold, R @ a.p_world_foothold, atol=1e-6)
    np.testing.assert_allclose(b.foothold_local, a.foothold_local, atol=1e-6)


def test_right_swing_goes_right():
    stance = -STANCE
    u_nom = np.array([0.2, -SEP / 2])
    sol = adjust_step(stance + [0.0, -0.05], stance, 0.0, Side.RIGHT, u_nom, [-0.05, 0.04], T_NOM, ELAPSED, OMEGA,
                      SEP, SOLE_W, StepAdjustmentConfig())
    assert -(SEP + 0.12) - 1e-9 <= sol.p_world_foothold[1] - stance[1] <= -(SOLE_W + 0.02) + 1e-9
    assert sol.p_world_foothold[1] < u_nom[1]


def test_config_is_validated():
    with pytest.raises(PlanningError, match="threshold"):
        StepAdjustmentConfig(threshold=0.0)
    with pytest.raises(PlanningError, match="min_single_support"):
        StepAdjustmentConfig(min_single_support=1.5, max_single_support=1.0)


# ---- the online adjuster on a planned walk -------------------------------------------------------------------

def _walk():
    plan = straight_walk(2, 0.2, foot_separation=SEP, timing=StepTiming(0.9, 0.115, 2.5, 1.0),
                         sole=SoleRectangle(0.2, SOLE_W), start=(0.0, 0.0, 0.0, 0.0))
    cfg = PatternGeneratorConfig(com_height=0.87, preview_horizon=1.6)
    return generate_walk(plan, cfg, p_world_com_init=np.array([0.0, 0.0, 0.87])), cfg


def test_adjuster_inside_the_region_does_nothing():
    walk, cfg = _walk()
    adj = StepAdjuster(walk, StepAdjustmentConfig(), cfg, SEP)
    k = 10 * int(round((walk.plan.lift_off_time(1) + 0.45) / walk.dt / 10))   # a check tick (every 10 ms)
    state = np.vstack([walk.p_world_com[k, :2], walk.v_world_com[k, :2], walk.a_world_com[k, :2]])
    assert adj.update(k, walk.p_world_dcm[k, :2] + [0.015, 0.0], state) is None
    assert adj.walk is walk and adj.count == 0
    assert adj.log[1] == pytest.approx(0.015)       # it did check
    assert adj.update(k, walk.p_world_dcm[k, :2] + [0.025, 0.0], state) is not None     # outside: it re-plans


def test_adjuster_replans_a_continuous_walk_onto_the_new_foothold():
    walk, cfg = _walk()
    adj = StepAdjuster(walk, StepAdjustmentConfig(), cfg, SEP)
    step = 1
    k = 10 * int(round((walk.plan.lift_off_time(step) + 0.45) / walk.dt / 10))
    dcm = walk.p_world_dcm[k, :2] + [0.06, 0.02]
    com = walk.p_world_com[k, :2] + [0.01, 0.0]
    vel = (dcm - com) * walk.omega
    new = adj.update(k, dcm, np.vstack([com, vel, np.zeros(2)]))
    assert new is not None and adj.count == 1
    t_adj, i, sol = adj.history[0]
    assert i == step
    side = walk.plan.steps[step].side
    foot = new.feet[side]
    td = k + int(np.argmax(foot.in_contact[k:]))
    assert abs((td - k) * walk.dt - sol.remaining_time) <= walk.dt
    assert td < int(round(walk.plan.touch_down_time(step) / walk.dt))         # shortened
    np.testing.assert_allclose(foot.p_world_sole[td, :2], sol.p_world_foothold, atol=1e-9)
    assert foot.p_world_sole[td, 0] > walk.plan.steps[step].p_world_sole[0] + 0.05     # further forward
    # continuity at the re-plan tick: the swing foot, the CoM starts at the measured state
    for a in ("p_world_sole", "v_world_sole", "a_world_sole"):
        np.testing.assert_allclose(getattr(foot, a)[k], getattr(walk.feet[side], a)[k], atol=1e-9)
    assert np.abs(np.diff(foot.p_world_sole[k - 5:td + 5], axis=0)).max() < 0.01    # no jump (1 cm per tick)
    np.testing.assert_allclose(new.p_world_com[k, :2], com, atol=1e-12)
    np.testing.assert_allclose(new.p_world_dcm[k, :2], dcm, atol=1e-9)
    # before the re-plan nothing changed; the later footsteps moved with the adjusted one
    np.testing.assert_array_equal(new.p_world_com[:k], walk.p_world_com[:k])
    np.testing.assert_allclose(new.plan.steps[2].p_world_sole[:2] - walk.plan.steps[2].p_world_sole[:2],
                               sol.p_world_foothold - walk.plan.steps[step].p_world_sole[:2], atol=1e-9)
    # the new plan stays viable: the ZMP reference is on the new foothold after touch-down, the CoM ends at rest
    ds = int(round(walk.plan.timing.double_support / walk.dt))
    np.testing.assert_allclose(new.p_world_zmp_ref[td + ds + 10, :2], sol.p_world_foothold, atol=1e-9)
    final = 0.5 * (new.plan.final_feet[Side.LEFT].p_world_sole + new.plan.final_feet[Side.RIGHT].p_world_sole)
    np.testing.assert_allclose(new.p_world_zmp_ref[-1, :2], final[:2], atol=1e-9)
    old_end = np.linalg.norm(walk.p_world_com[-1, :2] - walk.p_world_zmp_ref[-1, :2])
    assert np.linalg.norm(new.p_world_com[-1, :2] - final[:2]) < old_end + 0.01
    assert new.n_ticks == walk.n_ticks + (td - int(round(walk.plan.touch_down_time(step) / walk.dt)))


def _replan_mid_swing(replan_from: str, dcm_offset):
    """A walk's adjuster re-planning from `replan_from` in the second step's swing, the measured DCM off the plan's
    by `dcm_offset` (the measured CoM state zero: these modes do not use it); (walk, adjuster, tick, DCM, new walk)."""
    walk, cfg = _walk()
    adj = StepAdjuster(walk, StepAdjustmentConfig(replan_from=replan_from), cfg, SEP)
    k = 10 * int(round((walk.plan.lift_off_time(1) + 0.45) / walk.dt / 10))
    dcm = walk.p_world_dcm[k, :2] + dcm_offset
    new = adj.update(k, dcm, np.zeros((3, 2)))
    assert new is not None
    return walk, adj, k, dcm, new


def test_replan_from_the_plan_keeps_the_com_reference_continuous():
    walk, adj, k, dcm, new = _replan_mid_swing("planned", [0.06, 0.0])
    for a in ("p_world_com", "v_world_com", "a_world_com"):
        np.testing.assert_allclose(getattr(new, a)[k], getattr(walk, a)[k], atol=1e-12)
    assert adj.history[0][2].p_world_foothold[0] > walk.plan.steps[1].p_world_sole[0] + 0.05
    with pytest.raises(PlanningError, match="replan_from"):
        StepAdjustmentConfig(replan_from="guess")


def test_replan_from_the_dcm_keeps_the_com_position_and_takes_the_measured_dcm():
    walk, adj, k, dcm, new = _replan_mid_swing("dcm", [0.06, 0.02])
    for a in ("p_world_com", "a_world_com"):
        np.testing.assert_allclose(getattr(new, a)[k], getattr(walk, a)[k], atol=1e-12)
    np.testing.assert_allclose(new.p_world_dcm[k, :2], dcm, atol=1e-9)


def test_the_deadband_leaves_part_of_the_error_to_the_controller():
    walk, cfg = _walk()
    k = 10 * int(round((walk.plan.lift_off_time(1) + 0.45) / walk.dt / 10))
    err = np.array([0.06, 0.0])
    dcm = walk.p_world_dcm[k, :2] + err
    full = StepAdjuster(walk, StepAdjustmentConfig(threshold=0.05, replan_from="dcm"), cfg, SEP)
    part = StepAdjuster(walk, StepAdjustmentConfig(threshold=0.05, deadband=0.03, replan_from="dcm"), cfg, SEP)
    a, b = full.update(k, dcm, np.zeros((3, 2))), part.update(k, dcm, np.zeros((3, 2)))
    # the re-planned DCM: the measured one moved back towards the plan by the deadband
    np.testing.assert_allclose(b.p_world_dcm[k, :2], walk.p_world_dcm[k, :2] + err / 2, atol=1e-9)
    nominal = walk.plan.steps[1].p_world_sole[0]
    assert nominal < part.history[0][2].p_world_foothold[0] < full.history[0][2].p_world_foothold[0]
    assert part.update(k + 10, walk.p_world_dcm[k + 10, :2] + [0.045, 0.0], np.zeros((3, 2))) is None  # inside
    with pytest.raises(PlanningError, match="deadband"):
        StepAdjustmentConfig(threshold=0.05, deadband=0.05)


def test_a_swing_foot_that_landed_is_not_moved_again():
    walk, cfg = _walk()
    adj = StepAdjuster(walk, StepAdjustmentConfig(), cfg, SEP)
    side = walk.plan.steps[1].side
    lo = int(round(walk.plan.lift_off_time(1) / walk.dt))
    k = 10 * int(round((walk.plan.lift_off_time(1) + 0.6) / walk.dt / 10))
    state = np.zeros((3, 2))
    # still loaded just after lift-off (the foot leaving the ground late): that is no landing
    assert adj.update(lo + 1, walk.p_world_dcm[lo + 1, :2], state, frozenset(Side)) is None
    assert adj.update(lo + 2, walk.p_world_dcm[lo + 2, :2], state, frozenset({side.other})) is None  # in the air
    # loaded again before its touch-down: it landed early, its step is done
    assert adj.update(k, walk.p_world_dcm[k, :2] + [0.06, 0.0], state, frozenset(Side)) is None
    assert adj.count == 0 and adj.landed == {1}


def test_late_descent_holds_the_swing_foot_up_and_lands_it_on_the_foothold():
    walk, cfg = _walk()
    k = 10 * int(round((walk.plan.lift_off_time(1) + 0.45) / walk.dt / 10))     # the swing at its apex
    dcm = walk.p_world_dcm[k, :2] + [0.06, 0.0]
    stretched = StepAdjuster(walk, StepAdjustmentConfig(), cfg, SEP)
    late = StepAdjuster(walk, StepAdjustmentConfig(late_descent=0.4), cfg, SEP)
    a, b = stretched.update(k, dcm, np.zeros((3, 2))), late.update(k, dcm, np.zeros((3, 2)))
    assert a is not None and b is not None
    sol_a, sol_b = stretched.history[0][2], late.history[0][2]
    np.testing.assert_allclose(sol_b.p_world_foothold, sol_a.p_world_foothold)    # the QP does not change
    side = walk.plan.steps[1].side
    fa, fb = a.feet[side], b.feet[side]
    td = k + int(np.argmax(fb.in_contact[k:]))
    assert td == k + int(np.argmax(fa.in_contact[k:])) and td - k > 20           # the same (shortened) touch-down
    for name in ("p_world_sole", "v_world_sole", "a_world_sole"):                 # continuous at the re-plan
        np.testing.assert_allclose(getattr(fb, name)[k], getattr(walk.feet[side], name)[k], atol=1e-9)
    z_a, z_b = fa.p_world_sole[k:td + 1, 2], fb.p_world_sole[k:td + 1, 2]
    k1 = int(round(0.4 * (td - k)))
    assert z_b[k1] == pytest.approx(cfg.swing_apex_height, abs=1e-3)             # at the apex 40 % in
    k2 = int(round(0.7 * (td - k)))
    assert z_b[k2] > z_a[k2] + 0.01                                               # higher than the stretched profile
    assert np.abs(np.diff(z_b)).max() < 0.005 and z_b.min() > -1e-9               # smooth, never below the ground
    np.testing.assert_allclose(fb.p_world_sole[td], b.plan.steps[1].p_world_sole, atol=1e-9)   # on the foothold
    assert b.plan.steps[1].p_world_sole[0] > walk.plan.steps[1].p_world_sole[0] + 0.05
    for bad in (1.0, -0.1):
        with pytest.raises(PlanningError, match="late_descent"):
            StepAdjustmentConfig(late_descent=bad)


def test_late_descent_back_only_for_a_swing_foot_sent_back():
    walk, cfg = _walk()
    k = 10 * int(round((walk.plan.lift_off_time(1) + 0.45) / walk.dt / 10))     # the swing at its apex
    side = walk.plan.steps[1].side

    def height(dcm_error, **kw):
        adj = StepAdjuster(walk, StepAdjustmentConfig(**kw), cfg, SEP)
        new = adj.update(k, walk.p_world_dcm[k, :2] + dcm_error, np.zeros((3, 2)))
        assert new is not None
        return new.feet[side].p_world_sole[k:, 2], new.plan.steps[1].p_world_sole[0] - walk.feet[side].p_world_sole[k, 0]

    # pushed forwards: the foothold ahead of the foot, which keeps its travel: the stretched profile
    z_back, ahead = height([0.06, 0.0], late_descent=0.6, late_descent_back=True)
    assert ahead > 0.0
    np.testing.assert_allclose(z_back, height([0.06, 0.0])[0], atol=1e-12)
    assert np.abs(z_back - height([0.06, 0.0], late_descent=0.6)[0]).max() > 0.01
    # pushed backwards: the foothold behind the foot, which turns back: the late descent
    z_back, behind = height([-0.08, 0.0], late_descent=0.6, late_descent_back=True)
    assert behind < 0.0
    np.testing.assert_allclose(z_back, height([-0.08, 0.0], late_descent=0.6)[0], atol=1e-12)
    assert np.abs(z_back - height([-0.08, 0.0])[0]).max() > 0.01
