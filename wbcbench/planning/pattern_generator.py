"""Walking pattern generator: footsteps -> ZMP reference -> CoM by preview control -> per-tick references.

Paper 000, Section 5.1 (Kajita et al. 2003 preview control; the DCM deduced from the CoM by Eq. 2). The
generator is robot-model free: it takes a FootstepPlan and numbers (CoM height, gravity, dt).

ZMP reference (x, y; z is the support height), piecewise:
- initial double support: held at the initial CoM for at least the preview horizon (so the plan starts
  exactly at rest, without the start-up spike of a reference change already inside the horizon at t = 0),
  then moved to the first stance sole centre during the last `initial_shift` seconds;
- single support: at the stance sole centre (the sole rectangle centre, not the sole frame origin);
- double support between steps: moved from the old to the new stance sole centre over the whole phase;
- final double support: moved to the midpoint of the final sole centres over `final_shift`, then held.
Each move follows the quintic blend (zero velocity and acceleration at its ends) or a linear ramp.

CoM: x, y from ZMP preview control (see preview_control.py); z = com_height + support height, where a height
change (stairs) is blended with a quintic from the start of the ZMP move to the start of the next one (the
move plus the following single support). With `initial_com_height` the CoM starts at that height instead and
reaches com_height with a quintic before the first ZMP move (a walking height lower than the standing one).
On flat ground z is otherwise constant, the cart-table model is exact, and p_world_zmp reproduces the reference
up to the preview controller's tracking error (about 0.1 mm for the paper's 20 cm walk with the defaults). With
height changes (and during that descent) the cart-table ZMP ignores the vertical CoM acceleration: an
approximation.

Feet: at rest on their footsteps, swinging (swing.py) during single support; contact changes at the ticks
nearest to the plan's lift-off and touch-down times.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from ..errors import PlanningError
from ..types import GRAVITY
from .footsteps import Footstep, FootstepPlan
from .preview_control import PreviewGains, preview_gains, simulate_preview
from ..side import Side
from .swing import SwingTrajectory, foot_arrays, quintic_blend, write_swing
from .trajectory import ContactEvent, ContactEventKind, ContactSchedule, FootTrajectory, WalkTrajectory

__all__ = ["ZmpTransfer", "PatternGeneratorConfig", "zmp_reference", "generate_walk"]


class ZmpTransfer(enum.Enum):
    """Shape of a ZMP move between two support points."""

    SMOOTH = "smooth"  # quintic blend: zero velocity and acceleration at both ends
    LINEAR = "linear"  # constant velocity


def _positive(owner: str, name: str, value: float) -> None:
    if not isinstance(value, (int, float, np.floating, np.integer)) or not np.isfinite(value) or value <= 0.0:
        raise PlanningError(f"{owner}.{name} must be positive and finite, got {value!r}")


@dataclass(frozen=True)
class PatternGeneratorConfig:
    """Settings of the walking pattern generator.

    Attributes:
        com_height: CoM height above the support [m] (TALOS, half-sitting: about 0.87).
        dt: output tick period [s] (1 kHz by default).
        gravity: [m/s^2], positive.
        preview_horizon: preview horizon [s]. Kajita used 1.6 s with c_z = 0.814 m; at c_z = 0.87 m 1.6 s
            leaves 1.4 mm (20 cm steps) to 5 mm (60 cm) of ZMP tracking error, 2.5 s about 0.1-0.25 mm.
        preview_dt: period at which the preview controller runs [s], an integer multiple of dt; None for dt.
            Between its samples the CoM is evaluated exactly (piecewise-constant jerk, cubic in time).
        zmp_weight, jerk_weight: Qe and R of the preview LQ cost.
        zmp_transfer: shape of the ZMP moves.
        initial_shift: duration of the ZMP move from the initial CoM to the first stance foot [s]; the plan's
            initial double support must be >= preview_horizon + initial_shift.
        final_shift: duration of the ZMP move from the last stance foot to the final feet midpoint [s];
            <= the plan's final double support.
        swing_apex_height: swing apex above the higher end of each swing [m].
        swing_apex_phase: fraction of the swing at the apex, in (0, 1).
        swing_horizontal_window: (w0, w1) fraction of the swing during which the foot moves horizontally.
        initial_com_height: CoM height above the support at t = 0 [m] when it differs from com_height (a robot
            starting taller than the walking height); the CoM z then moves to com_height with a quintic (zero
            velocity and acceleration at both ends) from t = 0 to the start of the first ZMP move. None: the
            walk starts at com_height.
    """

    com_height: float
    dt: float = 1e-3
    gravity: float = GRAVITY
    preview_horizon: float = 2.5
    preview_dt: float | None = None
    zmp_weight: float = 1.0
    jerk_weight: float = 1e-8
    zmp_transfer: ZmpTransfer = ZmpTransfer.SMOOTH
    initial_shift: float = 0.8
    final_shift: float = 0.8
    swing_apex_height: float = 0.05
    swing_apex_phase: float = 0.5
    swing_horizontal_window: tuple[float, float] = (0.0, 1.0)
    initial_com_height: float | None = None

    def __post_init__(self) -> None:
        for name in ("com_height", "dt", "gravity", "preview_horizon", "zmp_weight", "jerk_weight",
                     "initial_shift", "final_shift"):
            _positive("PatternGeneratorConfig", name, getattr(self, name))
        if self.preview_dt is not None:
            _positive("PatternGeneratorConfig", "preview_dt", self.preview_dt)
            ratio = self.preview_dt / self.dt
            if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
                raise PlanningError(f"PatternGeneratorConfig.preview_dt ({self.preview_dt} s) must be an integer "
                                 f"multiple of dt ({self.dt} s)")
        if not isinstance(self.zmp_transfer, ZmpTransfer):
            try:
                object.__setattr__(self, "zmp_transfer", ZmpTransfer(self.zmp_transfer))
            except ValueError:
                raise PlanningError(f"PatternGeneratorConfig.zmp_transfer: unknown {self.zmp_transfer!r}; allowed: "
                                 f"{', '.join(z.value for z in ZmpTransfer)}") from None
        if self.initial_com_height is not None:
            _positive("PatternGeneratorConfig", "initial_com_height", self.initial_com_height)
        if not np.isfinite(self.swing_apex_height) or self.swing_apex_height < 0.0:
            raise PlanningError(f"PatternGeneratorConfig.swing_apex_height must be >= 0 [m], got "
                             f"{self.swing_apex_height!r}")
        if not 0.0 < self.swing_apex_phase < 1.0:
            raise PlanningError(f"PatternGeneratorConfig.swing_apex_phase must be in (0, 1), got "
                             f"{self.swing_apex_phase!r}")
        try:
            w0, w1 = (float(w) for w in self.swing_horizontal_window)
        except (TypeError, ValueError):
            raise PlanningError("PatternGeneratorConfig.swing_horizontal_window must be two numbers (w0, w1)") from None
        object.__setattr__(self, "swing_horizontal_window", (w0, w1))
        if not 0.0 <= w0 < w1 <= 1.0:
            raise PlanningError("PatternGeneratorConfig.swing_horizontal_window must satisfy 0 <= w0 < w1 <= 1")

    @property
    def omega(self) -> float:
        """sqrt(gravity / com_height) [1/s]."""
        return float(np.sqrt(self.gravity / self.com_height))

    def gains(self) -> PreviewGains:
        """The preview gains at preview_dt (or dt), cached."""
        return preview_gains(self.preview_dt or self.dt, self.com_height, self.gravity, self.preview_horizon,
                             self.zmp_weight, self.jerk_weight)


@dataclass(frozen=True)
class _Move:
    """The support point moves from p_from to p_to over ticks [start, end)."""

    start: int
    end: int
    p_from: np.ndarray
    p_to: np.ndarray


def _tick(t: float, dt: float) -> int:
    return int(round(t / dt))


def _sole_center(foot: Footstep, plan: FootstepPlan) -> np.ndarray:
    return plan.sole.center_in_world(foot.p_world_sole, foot.R_world_sole)


def _moves(plan: FootstepPlan, config: PatternGeneratorConfig, p_init: np.ndarray) -> tuple[list[_Move], int]:
    """The ZMP moves of a plan, and the number of ticks. Validates the timing against the config."""
    dt, timing = config.dt, plan.timing
    for name in ("single_support", "double_support", "initial_double_support", "final_double_support"):
        if getattr(timing, name) < dt - 1e-12:
            raise PlanningError(f"StepTiming.{name} ({getattr(timing, name)} s) is shorter than one tick ({dt} s)")
    if timing.initial_double_support < config.preview_horizon + config.initial_shift - 1e-9:
        raise PlanningError(
            f"StepTiming.initial_double_support ({timing.initial_double_support} s) must be at least "
            f"preview_horizon + initial_shift = {config.preview_horizon + config.initial_shift:g} s: the ZMP "
            "reference is held at the initial CoM for longer than the preview horizon so that the walk starts "
            "at rest without a start-up spike")
    if config.final_shift > timing.final_double_support + 1e-9:
        raise PlanningError(f"PatternGeneratorConfig.final_shift ({config.final_shift} s) must not exceed "
                         f"StepTiming.final_double_support ({timing.final_double_support} s)")
    n_ticks = _tick(plan.duration, dt) + 1
    moves: list[_Move] = []
    t_init = timing.initial_double_support
    if plan.n_steps == 0:
        feet = plan.initial_feet
        target = 0.5 * (_sole_center(feet[Side.LEFT], plan) + _sole_center(feet[Side.RIGHT], plan))
        moves.append(_Move(_tick(t_init - config.initial_shift, dt), _tick(t_init, dt), p_init, target))
        return moves, n_ticks
    stance = [_sole_center(plan.stance_foot(i), plan) for i in range(plan.n_steps)]
    moves.append(_Move(_tick(t_init - config.initial_shift, dt), _tick(t_init, dt), p_init, stance[0]))
    for i in range(plan.n_steps - 1):
        moves.append(_Move(_tick(plan.touch_down_time(i), dt), _tick(plan.lift_off_time(i + 1), dt),
                           stance[i], stance[i + 1]))
    final = plan.final_feet
    target = 0.5 * (_sole_center(final[Side.LEFT], plan) + _sole_center(final[Side.RIGHT], plan))
    t_last = plan.touch_down_time(plan.n_steps - 1)
    moves.append(_Move(_tick(t_last, dt), _tick(t_last + config.final_shift, dt), stance[-1], target))
    return moves, n_ticks


def _blend(k: np.ndarray, start: int, end: int, transfer: ZmpTransfer
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Blend value and its first two time derivatives per tick (derivatives per tick, not per second)."""
    span = max(end - start, 1)
    u = (k - start) / span
    if transfer is ZmpTransfer.LINEAR:
        s = np.clip(u, 0.0, 1.0)
        inside = (u > 0.0) & (u < 1.0)
        return s, np.where(inside, 1.0 / span, 0.0), np.zeros_like(s)
    q, dq, ddq = quintic_blend(u)
    return q, dq / span, ddq / span**2


def _default_p_init(plan: FootstepPlan) -> np.ndarray:
    feet = plan.initial_feet
    return 0.5 * (_sole_center(feet[Side.LEFT], plan) + _sole_center(feet[Side.RIGHT], plan))


def zmp_reference(plan: FootstepPlan, config: PatternGeneratorConfig,
                  p_world_com_init: np.ndarray | None = None) -> np.ndarray:
    """The planned ZMP per tick, shape (n, 3) [m] (z: support height). See the module docstring.

    Args:
        plan: footsteps and timing.
        config: generator settings.
        p_world_com_init: initial CoM, shape (2,) or (3,) [m]; the ZMP is held under it at the start.
            Default: midway between the initial sole centres.
    """
    p_init = _initial_point(plan, p_world_com_init)
    moves, n = _moves(plan, config, p_init)
    return _zmp_from_moves(moves, n, p_init, config.zmp_transfer)


def _initial_point(plan: FootstepPlan, p_world_com_init: np.ndarray | None) -> np.ndarray:
    base = _default_p_init(plan)
    if p_world_com_init is None:
        return base
    p = np.asarray(p_world_com_init, dtype=float).ravel()
    if p.shape not in ((2,), (3,)) or not np.all(np.isfinite(p)):
        raise PlanningError(f"p_world_com_init must be 2 or 3 finite numbers [m], got {p_world_com_init!r}")
    return np.array([p[0], p[1], base[2]])


def _zmp_from_moves(moves: list[_Move], n: int, p_init: np.ndarray, transfer: ZmpTransfer) -> np.ndarray:
    k = np.arange(n)
    zmp = np.tile(p_init, (n, 1))
    for m in moves:
        s, _, _ = _blend(k[m.start:], m.start, m.end, transfer)
        zmp[m.start:] = m.p_from + np.outer(s, m.p_to - m.p_from)
    return zmp


def _support_height(moves: list[_Move], n: int, z_init: float, dt: float) -> tuple[np.ndarray, ...]:
    """Support height for the CoM: each height change blended over its move and the following single support."""
    k = np.arange(n)
    z = np.full(n, z_init)
    dz = np.zeros(n)
    ddz = np.zeros(n)
    for i, m in enumerate(moves):
        if abs(m.p_to[2] - m.p_from[2]) < 1e-12:
            z[m.start:] = m.p_to[2]
            continue
        end = moves[i + 1].start if i + 1 < len(moves) else n - 1
        end = max(end, m.end)
        s, ds, dds = _blend(k[m.start:], m.start, end, ZmpTransfer.SMOOTH)
        h = m.p_to[2] - m.p_from[2]
        z[m.start:] = m.p_from[2] + h * s
        dz[m.start:] = h * ds / dt
        ddz[m.start:] = h * dds / dt**2
    return z, dz, ddz


def _com_horizontal(zmp_xy: np.ndarray, p_init_xy: np.ndarray, config: PatternGeneratorConfig
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CoM x-y position, velocity, acceleration per tick, each (n, 2), by preview control."""
    gains = config.gains()
    n = len(zmp_xy)
    x0 = np.vstack([p_init_xy, np.zeros(2), np.zeros(2)])
    if config.preview_dt is None:
        states, _ = simulate_preview(gains, zmp_xy, x0)
        return states[:, 0, :], states[:, 1, :], states[:, 2, :]
    m = int(round(config.preview_dt / config.dt))
    n_coarse = (n - 1) // m + 2
    idx = np.minimum(np.arange(n_coarse) * m, n - 1)
    states, jerk = simulate_preview(gains, zmp_xy[idx], x0)
    j = np.arange(n) // m
    tau = ((np.arange(n) - j * m) * config.dt)[:, None]
    c0, v0, a0, u = states[j, 0, :], states[j, 1, :], states[j, 2, :], jerk[j]
    c = c0 + v0 * tau + a0 * tau**2 / 2.0 + u * tau**3 / 6.0
    v = v0 + a0 * tau + u * tau**2 / 2.0
    a = a0 + u * tau
    return c, v, a


def _feet(plan: FootstepPlan, config: PatternGeneratorConfig, n: int
          ) -> tuple[dict[Side, FootTrajectory], ContactSchedule]:
    dt = config.dt
    t = np.arange(n) * dt
    arrays = {}
    for side in (Side.LEFT, Side.RIGHT):
        foot = plan.initial_feet[side]
        arrays[side] = {**foot_arrays(foot.p_world_sole, foot.R_world_sole, n), "contact": np.ones(n, bool)}
    events: list[ContactEvent] = []
    current = dict(plan.initial_feet)
    for i, step in enumerate(plan.steps):
        lo, td = _tick(plan.lift_off_time(i), dt), _tick(plan.touch_down_time(i), dt)
        swing = SwingTrajectory.between(current[step.side], step, lo * dt, (td - lo) * dt,
                                        apex_height=config.swing_apex_height, apex_phase=config.swing_apex_phase,
                                        horizontal_window=config.swing_horizontal_window)
        arr = arrays[step.side]
        # the swing, then from touch-down on exactly on the footstep, at rest (zeros already there)
        write_swing(arr, swing.sample(t[lo:td]), lo, td, step.p_world_sole, step.R_world_sole)
        arr["contact"][lo:td] = False
        events.append(ContactEvent(ContactEventKind.LIFT_OFF, step.side, lo, lo * dt, i))
        events.append(ContactEvent(ContactEventKind.TOUCH_DOWN, step.side, td, td * dt, i))
        current[step.side] = step
    feet = {s: FootTrajectory(s, a["p"], a["R"], a["v"], a["w"], a["a"], a["dw"], a["contact"])
            for s, a in arrays.items()}
    schedule = ContactSchedule(dt, {s: a["contact"] for s, a in arrays.items()},
                               tuple(sorted(events, key=lambda e: (e.tick, e.kind.value))))
    return feet, schedule


def generate_walk(plan: FootstepPlan, config: PatternGeneratorConfig,
                  p_world_com_init: np.ndarray | None = None) -> WalkTrajectory:
    """Generate the walking references for a footstep plan.

    Args:
        plan: footsteps and timing (validated on construction).
        config: generator settings.
        p_world_com_init: initial CoM x, y (shape (2,) or (3,); only x, y are used) [m]; the walk starts at
            rest there. Default: midway between the initial sole centres.

    Returns:
        WalkTrajectory with n = round(plan.duration / dt) + 1 ticks.

    Raises:
        ValueError: timing incompatible with the config (see PatternGeneratorConfig), bad inputs.
        PreviewControlError: the preview gains fail their accuracy checks.
    """
    if not isinstance(plan, FootstepPlan):
        raise PlanningError(f"plan must be a FootstepPlan, got {type(plan).__name__}")
    p_init = _initial_point(plan, p_world_com_init)
    moves, n = _moves(plan, config, p_init)
    zmp_ref = _zmp_from_moves(moves, n, p_init, config.zmp_transfer)
    c_xy, v_xy, a_xy = _com_horizontal(zmp_ref[:, :2], p_init[:2], config)
    z, dz, ddz = _support_height(moves, n, p_init[2], config.dt)
    if config.initial_com_height is not None:  # the descent (or rise) to com_height before the ZMP first moves
        k = np.arange(moves[0].start)
        s, ds, dds = _blend(k, 0, moves[0].start, ZmpTransfer.SMOOTH)
        h = config.initial_com_height - config.com_height
        z[k] += h * (1.0 - s)
        dz[k] -= h * ds / config.dt
        ddz[k] -= h * dds / config.dt**2
    com = np.column_stack([c_xy, z + config.com_height])
    vcom = np.column_stack([v_xy, dz])
    acom = np.column_stack([a_xy, ddz])
    zmp = np.column_stack([c_xy - config.com_height / config.gravity * a_xy, zmp_ref[:, 2]])
    omega = config.omega
    dcm = com + vcom / omega
    feet, schedule = _feet(plan, config, n)
    return WalkTrajectory(config.dt, config.com_height, config.gravity, omega, com, vcom, acom, zmp_ref, zmp, dcm,
                          feet, schedule, plan.sole, plan)
