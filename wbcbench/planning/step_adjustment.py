"""DCM-based step adjustment: when the measured DCM leaves its planned region during single support, the next
foothold and the remaining step time are re-planned so that the DCM ends the step at an offset from the new
foothold that keeps the gait viable (Khadiv, Herzog, Moosavian, Righetti 2016, "Step timing adjustment: a step
toward generating robust gaits"; Englsberger et al. 2015 for the DCM).

During single support the ZMP stays on the stance sole centre p, and the linear inverted pendulum's DCM diverges
from it: xi(t) = p + (xi_0 - p) exp(omega t). With tau = exp(omega T) for the remaining single-support time T,
the DCM at touch-down is p + (xi_0 - p) tau; it must equal the next foothold u plus a DCM offset b:

    u + b - (xi_0 - p) tau = p                                            (Khadiv 2016, Eq. 9)

The step-adjustment QP, in the stance sole frame (x forward, y to the left, origin p), over x = (u, tau, b):

    min  w_step |u - u_nom|^2 + w_time (tau - tau_nom)^2 + w_offset |b - b_nom|^2
    s.t. u + b - e tau = 0                          e = xi_0 - p, the measured DCM in the stance frame
         -max_backward <= u_x <= max_forward       (the robot profile's `stepping` limits)
         min_width <= s u_y <= width + max_lateral  s = +1 for a left swing foot, -1 for a right one;
                                                     min_width = sole width + min_clearance: no collision
         exp(omega T_min) <= tau <= exp(omega T_max) (remaining time bounds, when the timing adapts)

u_nom, b_nom, tau_nom come from the nominal plan (the foothold, the plan's DCM at touch-down minus that foothold,
the planned remaining time). Solved with daqp (`wbcbench.qp`); with the timing fixed tau is a constant and the
QP keeps u and b only. The solution is unique (H positive definite).

Once the swing foot's ankle F/T sensor finds it loaded again after it left the ground (it landed, possibly
before its reference: a position-controlled robot leaning towards it puts it lower than its model does), its step
is not adjusted again. A controller's task set may carry its own settings (`step_adjustment:`, for the keys the
scenario leaves; TALOS' IK and TSID position: a threshold of 5 cm, a deadband, re-plans from the DCM; TSID position
also a late descent of the re-planned swing, IK one of a swing sent back behind its foot).

`replan_walk` then re-plans the references from the current tick: the adjusted step and every later footstep
translated by the foothold's change (the rest of the gait keeps its shape), the remaining single support
stretched or shortened, the ZMP reference rebuilt from the new footholds, the CoM x-y from ZMP preview control
started at the measured CoM (the pattern generator's controller, re-run from the current state), and the swing
foot on a quintic from its current reference position, velocity and acceleration to the new foothold (its height
either the old remaining profile stretched to the new time or, with `late_descent`, brought to the apex height
over a share of the remaining time before it descends: a position-controlled robot leaning towards its swing foot
otherwise puts that foot on the ground short of the foothold; with `late_descent_back`, only for a swing foot
whose new foothold lies behind it along its travel).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import PlanningError
from ..side import Side
from .footsteps import FootstepPlan
from .pattern_generator import PatternGeneratorConfig, _moves, _sole_center, _support_height, _zmp_from_moves
from .pattern_generator import _feet as _plan_feet
from .preview_control import simulate_preview
from .swing import quintic_blend, quintic_from_state
from .trajectory import ContactEvent, ContactEventKind, ContactSchedule, FootTrajectory, WalkTrajectory

__all__ = ["StepAdjustmentConfig", "StepAdjustment", "adjust_step", "replan_walk", "StepAdjuster", "parse_settings"]


REPLAN_FROM = ("measured", "planned", "dcm")


#: the settings that must be > 0 and >= 0 (`StepAdjustmentConfig`, `parse_settings`)
_POSITIVE = ("threshold", "period", "max_forward", "max_backward", "max_lateral", "min_single_support",
             "max_single_support", "min_remaining", "w_step", "w_time", "w_offset")
_NONNEGATIVE = ("min_clearance", "min_change", "contact_force", "deadband", "late_descent")


@dataclass(frozen=True)
class StepAdjustmentConfig:
    """Settings of the step adjustment.

    Attributes:
        threshold: the DCM error (measured minus planned, horizontal norm) that triggers an adjustment [m].
        period: how often the DCM error is checked [s] (at most every control tick).
        max_forward, max_backward: forward / backward offset of the new foothold from the stance foot [m].
        max_lateral: lateral offset beyond the nominal foot separation [m].
        min_clearance: least gap between the two footprints sideways [m].
        adapt_timing: re-plan the remaining single-support time as well as the foothold.
        min_single_support, max_single_support: bounds on the adjusted single support's total duration [s].
        min_remaining: no adjustment when less single support than this remains [s] (the swing foot could not
            reach a new foothold); also the least remaining time the timing adaptation may choose.
        w_step, w_time, w_offset: QP weights on the foothold [1/m^2], tau [-] and DCM offset [1/m^2] changes.
        min_change: a solution moving the foothold by less than this [m] and the touch-down by less than one
            check period is not applied (no re-plan for nothing).
        contact_force: a swing foot whose ankle F/T sensor, after reading less, reads a larger normal force [N] has
            touched down (early: a position-controlled robot's foot may land before its reference does); its step
            is then no longer adjusted (a new foothold would drag the loaded foot along the ground, a later
            touch-down lift it again).
        deadband: the part of the DCM error [m] (< threshold) left to the controller's own balance feedback: the
            QP and a "dcm" re-plan take the measured DCM moved back towards the plan's by this much (a
            position-controlled scheme's stabilizer takes small errors itself; both reacting to the whole error
            over-stepped).
        replan_from: the CoM state the re-planned CoM starts from: "measured" (the push's momentum becomes
            part of the plan), "planned" (the reference stays continuous; only the footholds and timing
            change, the controller's own feedback handles the error) or "dcm" (the plan's CoM position and
            acceleration, the velocity that puts the plan's DCM on the measured one, less the deadband: the
            position reference does not jump to a measured CoM that lags it).
        late_descent: the share (< 1) of a re-planned swing's remaining time in which the swing foot goes from its
            current height (and velocity) to the apex height above the foothold; it descends in the rest (0: the
            old remaining height profile, stretched to the new time). A position-controlled robot leaning towards
            its swing foot (after a push) puts that foot lower than its reference: with the stretched profile of a
            shortened swing it touched down short of the foothold, and the rest of the swing dragged it, loaded,
            along the ground.
        late_descent_back: the late descent only for a swing whose new foothold lies behind the swing foot's
            reference along its travel (the foot turns back: pushed backwards), every other re-planned swing with
            the stretched old profile.
    """

    threshold: float = 0.02
    period: float = 0.01
    max_forward: float = 0.30
    max_backward: float = 0.20
    max_lateral: float = 0.12
    min_clearance: float = 0.02
    adapt_timing: bool = True
    min_single_support: float = 0.45
    max_single_support: float = 1.2
    min_remaining: float = 0.15
    w_step: float = 1.0
    w_time: float = 0.1
    w_offset: float = 100.0
    min_change: float = 0.005
    contact_force: float = 50.0
    deadband: float = 0.0
    replan_from: str = "measured"
    late_descent: float = 0.0
    late_descent_back: bool = False

    def __post_init__(self) -> None:
        if self.replan_from not in REPLAN_FROM:
            raise PlanningError(f"StepAdjustmentConfig.replan_from: unknown {self.replan_from!r}; allowed: "
                                f"{', '.join(REPLAN_FROM)}")
        for name in _POSITIVE:
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not np.isfinite(v) or v <= 0.0:
                raise PlanningError(f"StepAdjustmentConfig.{name} must be > 0, got {v!r}")
        if not 0.0 <= self.deadband < self.threshold:
            raise PlanningError(f"StepAdjustmentConfig.deadband must be >= 0 and below threshold ({self.threshold} m), "
                                f"got {self.deadband!r}")
        for name in _NONNEGATIVE:  # (the deadband checked above)
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not np.isfinite(v) or v < 0.0:
                raise PlanningError(f"StepAdjustmentConfig.{name} must be >= 0, got {v!r}")
        if not self.late_descent < 1.0:
            raise PlanningError(f"StepAdjustmentConfig.late_descent must be below 1, got {self.late_descent!r}")
        if self.min_single_support > self.max_single_support:
            raise PlanningError(f"StepAdjustmentConfig.min_single_support ({self.min_single_support} s) must not "
                                f"exceed max_single_support ({self.max_single_support} s)")

    @classmethod
    def from_stepping(cls, spec, **overrides) -> "StepAdjustmentConfig":
        """Limits from a robot profile's `SteppingSpec` (max_forward, max_backward, max_lateral, min_clearance)."""
        base = dict(max_forward=spec.max_forward, max_backward=spec.max_backward, max_lateral=spec.max_lateral,
                    min_clearance=spec.min_clearance)
        return cls(**{**base, **overrides})


def parse_settings(sec, defaults: StepAdjustmentConfig | None = None) -> dict:
    """The settings of a `step_adjustment:` section (a `wbcbench.config.Section`; errors name its file and key) as
    keyword arguments of `StepAdjustmentConfig`: every field, the missing ones from `defaults`; without
    `defaults`, only the keys the section gives."""
    kw = {}
    for names, check in ((_POSITIVE, {"positive": True}), (_NONNEGATIVE, {"min": 0.0})):
        for name in names:
            if defaults is not None or sec.has(name):
                kw[name] = sec.float(name, getattr(defaults, name, None), **check)
    for name in ("adapt_timing", "late_descent_back"):
        if defaults is not None or sec.has(name):
            kw[name] = sec.bool(name, getattr(defaults, name, None))
    if defaults is not None or sec.has("replan_from"):
        kw["replan_from"] = sec.str("replan_from", getattr(defaults, "replan_from", None), choices=list(REPLAN_FROM))
    return kw


@dataclass(frozen=True)
class StepAdjustment:
    """The solution of the step-adjustment QP.

    Attributes:
        p_world_foothold: the new foothold (sole centre) x, y in the world, shape (2,) [m].
        remaining_time: the single-support time left until touch-down [s].
        dcm_offset: b, the DCM at touch-down minus the foothold, world frame, shape (2,) [m].
        foothold_local: the foothold in the stance sole frame (x forward, y left), shape (2,) [m].
    """

    p_world_foothold: np.ndarray
    remaining_time: float
    dcm_offset: np.ndarray
    foothold_local: np.ndarray


def _rot2(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def adjust_step(p_world_dcm: np.ndarray, p_world_stance: np.ndarray, stance_yaw: float, swing: Side,
                p_world_foothold_nom: np.ndarray, dcm_offset_nom: np.ndarray, remaining_nom: float,
                elapsed: float, omega: float, foot_separation: float, sole_width: float,
                config: StepAdjustmentConfig, solver=None) -> StepAdjustment:
    """Solve the step-adjustment QP (module docstring) with daqp.

    Args:
        p_world_dcm: measured DCM x, y [m]. p_world_stance: stance sole centre x, y [m].
        stance_yaw: heading of the stance sole [rad]. swing: the swinging foot.
        p_world_foothold_nom: nominal next foothold (sole centre) x, y [m].
        dcm_offset_nom: nominal DCM offset at touch-down (world frame) x, y [m].
        remaining_nom: nominal single-support time left [s]. elapsed: single-support time already spent [s].
        omega: LIPM natural frequency [1/s]. foot_separation: nominal lateral distance of the feet [m].
        sole_width: [m]. config: the settings. solver: a `QPSolver` to reuse (default: a new daqp one).
    """
    from ..qp import QPProblem, make_solver

    R = _rot2(stance_yaw)
    p = np.asarray(p_world_stance, float)[:2]
    e = R.T @ (np.asarray(p_world_dcm, float)[:2] - p)
    u_nom = R.T @ (np.asarray(p_world_foothold_nom, float)[:2] - p)
    b_nom = R.T @ np.asarray(dcm_offset_nom, float)[:2]
    s = swing.sign
    lo_y, hi_y = sole_width + config.min_clearance, foot_separation + config.max_lateral
    lb_u = np.array([-config.max_backward, lo_y if s > 0 else -hi_y])
    ub_u = np.array([config.max_forward, hi_y if s > 0 else -lo_y])
    tau_nom = float(np.exp(omega * remaining_nom))
    if config.adapt_timing:
        t_lo = max(config.min_remaining, config.min_single_support - elapsed)
        t_hi = max(t_lo, config.max_single_support - elapsed)
        tau_lo, tau_hi = float(np.exp(omega * t_lo)), float(np.exp(omega * t_hi))
        # x = (u_x, u_y, tau, b_x, b_y); tau scaled by tau_nom so that the weights compare like units
        H = 2.0 * np.diag([config.w_step, config.w_step, config.w_time, config.w_offset, config.w_offset])
        x_nom = np.array([*u_nom, 1.0, *b_nom])
        A = np.array([[1.0, 0.0, -e[0] * tau_nom, 1.0, 0.0], [0.0, 1.0, -e[1] * tau_nom, 0.0, 1.0]])
        lb = np.array([*lb_u, tau_lo / tau_nom, -np.inf, -np.inf])
        ub = np.array([*ub_u, tau_hi / tau_nom, np.inf, np.inf])
    else:
        # tau fixed: x = (u_x, u_y, b_x, b_y), u + b = e tau_nom
        H = 2.0 * np.diag([config.w_step, config.w_step, config.w_offset, config.w_offset])
        x_nom = np.array([*u_nom, *b_nom])
        A = np.array([[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0]])
        lb = np.array([*lb_u, -np.inf, -np.inf])
        ub = np.array([*ub_u, np.inf, np.inf])
    b_eq = np.zeros(2) if config.adapt_timing else e * tau_nom
    problem = QPProblem(H, -H @ x_nom, A_eq=A, b_eq=b_eq, lb=lb, ub=ub)
    result = (solver or make_solver("daqp")).solve(problem)
    if not result.ok:
        raise PlanningError(f"step adjustment QP failed: {result.status.name}")
    x = result.x
    u = x[:2]
    if config.adapt_timing:
        tau, b = x[2] * tau_nom, x[3:5]
    else:
        tau, b = tau_nom, x[2:4]
    return StepAdjustment(p + R @ u, float(np.log(tau) / omega), R @ b, u.copy())


# ---- re-planning the references ---------------------------------------------------------------------------


def _translated_plan(plan: FootstepPlan, step: int, delta_xy: np.ndarray) -> FootstepPlan:
    """The plan with footstep `step` and every later one moved by delta_xy [m] (the gait keeps its shape)."""
    d = np.array([delta_xy[0], delta_xy[1], 0.0])
    steps = tuple(f.moved_to(f.p_world_sole + d, f.R_world_sole) if i >= step else f
                  for i, f in enumerate(plan.steps))
    return FootstepPlan(plan.initial_feet, steps, plan.timing, plan.sole, plan.limits)


def replan_walk(current: WalkTrajectory, plan: FootstepPlan, config: PatternGeneratorConfig, k0: int, step: int,
                shift_before: int, td_new: int, com_state: np.ndarray, late_descent: float = 0.0,
                late_descent_back: bool = False) -> WalkTrajectory:
    """The walk re-planned from tick k0, inside step `step`'s single support (module docstring).

    Args:
        current: the references used so far (ticks before k0 are kept).
        plan: the footstep plan with the adjusted foothold, in the nominal (unshifted) timing.
        config: the pattern generator's settings.
        k0: the current tick. step: the index of the swinging step.
        shift_before: ticks by which earlier adjustments moved this step's lift-off (sum of their time changes).
        td_new: the new touch-down tick of this step.
        com_state: the CoM to start from: (position, velocity, acceleration) x-y, shape (3, 2).
        late_descent, late_descent_back: the swing foot's height profile (`StepAdjustmentConfig`).
    """
    dt = config.dt
    p_init = np.array([*current.p_world_com[0, :2], current.p_world_zmp_ref[0, 2]])
    moves, n_mod = _moves(plan, config, p_init)
    zmp_mod = _zmp_from_moves(moves, n_mod, p_init, config.zmp_transfer)
    z_mod, dz_mod, ddz_mod = _support_height(moves, n_mod, p_init[2], dt)
    feet_mod, _ = _plan_feet(plan, config, n_mod)
    td_nom = int(round(plan.touch_down_time(step) / dt))
    shift = td_new - (td_nom + shift_before)      # this step's change of touch-down [ticks]
    n_new = n_mod + shift_before + shift
    # the tick of the nominal-timing arrays each new tick reads (single support: the ZMP and stance are constant)
    k = np.arange(k0, n_new)
    src = np.where(k < td_new, np.minimum(k - shift_before, td_nom - 1), k - shift_before - shift)
    src = np.clip(src, 0, n_mod - 1)

    def cat(old: np.ndarray, new: np.ndarray) -> np.ndarray:
        return np.concatenate([old[:k0], new])

    zmp_ref = cat(current.p_world_zmp_ref, zmp_mod[src])
    states, _ = simulate_preview(config.gains(), zmp_ref[k0:, :2], np.asarray(com_state, float))
    gz = config.gravity
    com = cat(current.p_world_com, np.column_stack([states[:, 0, :], z_mod[src] + config.com_height]))
    vcom = cat(current.v_world_com, np.column_stack([states[:, 1, :], dz_mod[src]]))
    acom = cat(current.a_world_com, np.column_stack([states[:, 2, :], ddz_mod[src]]))
    zmp = np.column_stack([com[:, :2] - config.com_height / gz * acom[:, :2], zmp_ref[:, 2]])
    dcm = com + vcom / config.omega
    swing_side = plan.steps[step].side
    feet = {}
    for s, f in current.feet.items():
        m = feet_mod[s]
        arr = {name: cat(getattr(f, name), getattr(m, name)[src])
               for name in ("p_world_sole", "R_world_sole", "v_world_sole", "w_world_sole", "a_world_sole",
                            "dw_world_sole", "in_contact")}
        if s is swing_side:
            if late_descent_back and float(np.dot(plan.steps[step].p_world_sole[:2] - f.p_world_sole[k0, :2],
                                                  f.v_world_sole[k0, :2])) >= 0.0:
                late_descent = 0.0     # the foot is not turned back: the stretched profile
            _replan_swing(arr, f, k0, td_new, plan.steps[step].p_world_sole, dt, late_descent,
                          config.swing_apex_height)
        feet[s] = FootTrajectory(s, *(arr[n] for n in ("p_world_sole", "R_world_sole", "v_world_sole",
                                                        "w_world_sole", "a_world_sole", "dw_world_sole",
                                                        "in_contact")))
    schedule = _schedule(feet, dt)
    return WalkTrajectory(dt, current.com_height, current.gravity, current.omega, com, vcom, acom, zmp_ref, zmp, dcm,
                          feet, schedule, current.sole, plan)


def _replan_swing(arr: dict, old: FootTrajectory, k0: int, td_new: int, p_end: np.ndarray, dt: float,
                  late_descent: float = 0.0, apex: float = 0.0) -> None:
    """The swing foot from tick k0 to td_new: horizontally a quintic from its current reference state to the new
    foothold; in rotation the remaining old profile, stretched to the new remaining time (constant on straight
    walks, only re-timed); vertically, without `late_descent`, the old profile stretched as well (with a correction
    keeping its velocity and acceleration continuous at k0), with `late_descent` (in (0, 1)) a quintic from the
    current height, velocity and acceleration to `apex` [m] above the foothold, at rest, over that share of the
    remaining time, then the descent to the foothold in the rest."""
    td_old = k0 + int(np.argmax(old.in_contact[k0:])) if old.in_contact[k0:].any() else len(old.in_contact)
    n_rem = td_new - k0
    if n_rem <= 0:
        return
    t = np.arange(n_rem) * dt
    p, v, a = quintic_from_state(old.p_world_sole[k0, :2], old.v_world_sole[k0, :2], old.a_world_sole[k0, :2],
                                  p_end[:2], n_rem * dt, t)
    sl = slice(k0, td_new)
    arr["p_world_sole"][sl, :2], arr["v_world_sole"][sl, :2], arr["a_world_sole"][sl, :2] = p, v, a
    # height and rotation: the old remaining profile [k0, td_old) mapped onto [k0, td_new)
    scale = (td_old - k0) / n_rem
    src = np.minimum(k0 + np.round(np.arange(n_rem) * scale).astype(int), max(td_old - 1, k0))
    if late_descent > 0.0:
        z, vz, az = _late_descent(old.p_world_sole[k0, 2], old.v_world_sole[k0, 2], old.a_world_sole[k0, 2],
                                  p_end[2], apex, late_descent, n_rem * dt, t)
        arr["p_world_sole"][sl, 2], arr["v_world_sole"][sl, 2], arr["a_world_sole"][sl, 2] = z, vz, az
    else:
        # plus a correction that starts with the old profile's velocity and acceleration and vanishes at
        # touch-down, so that the height stays C2 at the re-plan tick
        dz, dvz, daz = quintic_from_state(0.0, old.v_world_sole[k0, 2] * (1.0 - scale),
                                           old.a_world_sole[k0, 2] * (1.0 - scale**2), 0.0, n_rem * dt, t)
        arr["p_world_sole"][sl, 2] = old.p_world_sole[src, 2] + dz[:, 0]
        arr["v_world_sole"][sl, 2] = old.v_world_sole[src, 2] * scale + dvz[:, 0]
        arr["a_world_sole"][sl, 2] = old.a_world_sole[src, 2] * scale**2 + daz[:, 0]
    arr["R_world_sole"][sl] = old.R_world_sole[src]
    arr["w_world_sole"][sl] = old.w_world_sole[src] * scale
    arr["dw_world_sole"][sl] = old.dw_world_sole[src] * scale**2
    arr["in_contact"][sl] = False


def _late_descent(z0: float, v0: float, a0: float, z1: float, apex: float, share: float, T: float,
                  t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Height, its velocity and acceleration at the times t in [0, T]: a quintic from (z0, v0, a0) to z1 + apex
    at rest over the first `share` of T, then a minimum-jerk descent to z1 in the rest."""
    T1 = max(share * T, min(T, 1e-3))
    T2 = max(T - T1, 1e-3)
    z, vz, az = quintic_from_state(z0, v0, a0, z1 + apex, T1, t)
    b, db, ddb = quintic_blend((t - T1) / T2)
    return z[:, 0] - apex * b, vz[:, 0] - apex * db / T2, az[:, 0] - apex * ddb / T2**2


def _schedule(feet: dict, dt: float) -> ContactSchedule:
    """The contact schedule read from the feet's contact arrays (events numbered in order per kind)."""
    events = []
    counters = {ContactEventKind.LIFT_OFF: 0, ContactEventKind.TOUCH_DOWN: 0}
    changes = []
    for s, f in feet.items():
        c = np.asarray(f.in_contact, bool)
        for k in np.flatnonzero(c[1:] != c[:-1]) + 1:
            changes.append((int(k), ContactEventKind.TOUCH_DOWN if c[k] else ContactEventKind.LIFT_OFF, s))
    for k, kind, s in sorted(changes, key=lambda e: (e[0], e[1].value)):
        events.append(ContactEvent(kind, s, k, k * dt, counters[kind]))
        counters[kind] += 1
    return ContactSchedule(dt, {s: f.in_contact for s, f in feet.items()}, tuple(events))


# ---- the online loop ------------------------------------------------------------------------------------


class StepAdjuster:
    """Online step adjustment of a flat walk: `update(tick, dcm, com_state)` every control tick with the measured
    DCM and CoM; returns the re-planned WalkTrajectory when it changed, else None. `walk` is the current one.

    Args:
        walk: the nominal walk (from `generate_walk`). config: step adjustment settings.
        pg_config: the pattern generator's settings the walk was made with.
        foot_separation: nominal lateral distance between the feet [m].
    """

    LOG_LABELS = ("active", "dcm_error", "foothold_dx", "foothold_dy", "touch_down_shift", "count")

    def __init__(self, walk: WalkTrajectory, config: StepAdjustmentConfig, pg_config: PatternGeneratorConfig,
                 foot_separation: float):
        from ..qp import make_solver

        self.nominal = walk
        self.walk = walk
        self.config = config
        self.pg_config = pg_config
        self.foot_separation = foot_separation
        self.plan = walk.plan
        self.solver = make_solver("daqp")
        self.dt = walk.dt
        self.every = max(1, int(round(config.period / walk.dt)))
        plan = walk.plan
        self.lift_off = [int(round(plan.lift_off_time(i) / walk.dt)) for i in range(plan.n_steps)]
        self.touch_down = [int(round(plan.touch_down_time(i) / walk.dt)) for i in range(plan.n_steps)]
        # nominal foothold (sole centre) and DCM offset at touch-down, per step
        self.foothold_nom = [_sole_center(f, plan)[:2] for f in plan.steps]
        self.offset_nom = [walk.p_world_dcm[min(td, walk.n_ticks - 1), :2] - u
                           for td, u in zip(self.touch_down, self.foothold_nom)]
        self.shift = [0] * plan.n_steps          # touch-down change of each step [ticks]
        self.delta = np.zeros(2)                 # cumulative foothold translation of the plan [m]
        self.step_delta: dict[int, np.ndarray] = {}   # the translation each step's own adjustments added [m]
        self.count = 0
        self.airborne: set[int] = set()   # steps whose swing foot the F/T sensors found unloaded
        self.landed: set[int] = set()     # steps whose swing foot was loaded again after that (touched down)
        self.log = np.zeros(len(self.LOG_LABELS))
        self.history: list[tuple[float, int, StepAdjustment]] = []

    def _step_at(self, tick: int) -> int | None:
        """The step whose single support contains `tick` (in the current, shifted timing), or None."""
        before = 0
        for i, (lo, td) in enumerate(zip(self.lift_off, self.touch_down)):
            if lo + before <= tick < td + before + self.shift[i]:
                return i
            before += self.shift[i]
        return None

    def update(self, tick: int, p_world_dcm: np.ndarray, com_state: np.ndarray,
               loaded: frozenset = frozenset()) -> WalkTrajectory | None:
        """One control tick: measured DCM x, y [m] and CoM (position, velocity, acceleration) x-y, shape (3, 2);
        `loaded`: the feet the F/T sensors find loaded (normal force above `contact_force`)."""
        self.log[0] = 0.0
        i = self._step_at(tick)
        if i is not None:  # a swing foot loaded again after it left the ground has landed: its step is done
            side = self.plan.steps[i].side
            if side not in loaded:
                self.airborne.add(i)
            elif i in self.airborne:
                self.landed.add(i)
        if tick % self.every:
            return None
        k = min(tick, self.walk.n_ticks - 1)
        err = float(np.linalg.norm(np.asarray(p_world_dcm, float)[:2] - self.walk.p_world_dcm[k, :2]))
        self.log[1] = err
        if i is None or err <= self.config.threshold:
            return None
        cfg, dt, plan = self.config, self.dt, self.plan
        before = sum(self.shift[:i])
        lo, td = self.lift_off[i] + before, self.touch_down[i] + before + self.shift[i]
        remaining = (td - tick) * dt
        if remaining < cfg.min_remaining or i in self.landed:
            return None
        if cfg.deadband > 0.0:  # the part of the error the controller's own balance feedback is left to absorb
            xi_plan = self.walk.p_world_dcm[k, :2]
            p_world_dcm = xi_plan + (np.asarray(p_world_dcm, float)[:2] - xi_plan) * (1.0 - cfg.deadband / err)
        stance = plan.stance_foot(i)
        p_stance = _sole_center(stance, plan)[:2]
        # nominal values in the current (translated) plan: the foothold the gait had, moved with earlier steps
        own = self.step_delta.get(i, np.zeros(2))
        d_prev = self.delta - own
        u_nom = self.foothold_nom[i] + d_prev
        remaining_nom = (self.touch_down[i] + before - tick) * dt
        sol = adjust_step(p_world_dcm, p_stance, stance.yaw, plan.steps[i].side, u_nom, self.offset_nom[i],
                          max(remaining_nom, cfg.min_remaining), (tick - lo) * dt, self.walk.omega,
                          self.foot_separation, plan.sole.width, cfg, self.solver)
        u_now = _sole_center(plan.steps[i], plan)[:2]
        td_new = tick + max(int(round(sol.remaining_time / dt)), 1)
        if not cfg.adapt_timing:
            td_new = td
        if np.linalg.norm(sol.p_world_foothold - u_now) < cfg.min_change and abs(td_new - td) < self.every:
            return None
        self._replan(tick, i, before, td_new, sol.p_world_foothold - u_now, p_world_dcm, com_state, err)
        self.history.append((tick * dt, i, sol))
        return self.walk

    def _replan(self, tick: int, i: int, before: int, td_new: int, move: np.ndarray, p_world_dcm: np.ndarray,
                com_state: np.ndarray, err: float) -> None:
        """Step i's foothold (and every later one) moved by `move` [m], its touch-down at tick `td_new`, the
        references re-planned from `tick` (the CoM from the state `replan_from` says)."""
        cfg, plan = self.config, self.plan
        k = min(tick, self.walk.n_ticks - 1)
        own = self.step_delta.get(i, np.zeros(2))
        new_plan = _translated_plan(plan, i, move)
        if cfg.replan_from == "planned":
            w = self.walk
            com_state = np.vstack([w.p_world_com[k, :2], w.v_world_com[k, :2], w.a_world_com[k, :2]])
        elif cfg.replan_from == "dcm":  # the plan's CoM position, the velocity that puts its DCM on the measured one
            w = self.walk
            v = w.v_world_com[k, :2] + w.omega * (np.asarray(p_world_dcm, float)[:2] - w.p_world_dcm[k, :2])
            com_state = np.vstack([w.p_world_com[k, :2], v, w.a_world_com[k, :2]])
        self.walk = replan_walk(self.walk, new_plan, self.pg_config, tick, i, before, td_new, com_state,
                                cfg.late_descent, cfg.late_descent_back)
        self.plan = new_plan
        self.step_delta[i] = own + move
        self.delta = self.delta + move
        self.shift[i] = td_new - (self.touch_down[i] + before)
        self.count += 1
        d = _sole_center(new_plan.steps[i], new_plan)[:2] - self.foothold_nom[i] - (self.delta - self.step_delta[i])
        self.log[:] = (1.0, err, d[0], d[1], self.shift[i] * self.dt, self.count)
