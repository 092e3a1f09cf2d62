"""Stepping teleoperation (`locomotion: stepping`): the operator's steps become the robot's, through the walking
stack; the upper body keeps being retargeted, carried by the robot's walk.

1. **Detection** (`human/locomotion.detect_steps`): each operator step's side, lift-off and touch-down times and
   the ankle's new position and heading, from the foot segments' height and speed with hysteresis.
2. **Scaling**: the retargeting's calibration maps the suit's world onto the robot's (`T_world_suit`, the
   operator's feet on the robot's feet at the calibration frame) and scales about the robot's feet frame by the
   robot/human proportion k. A step's target is the robot's sole at the start moved by k times the operator's
   ankle displacement since the calibration frame (horizontal, in the robot's world), turned by the foot's
   heading change.
3. **Limits**: each target is clamped in the stance sole's frame by the robot profile's `stepping` limits:
   forward `max_forward`, backward `max_backward`, sideways between the soles' width plus `min_clearance` and the
   initial separation plus `max_lateral`, turn `max_turn`; a footprint still overlapping the stance one is moved
   outwards. Steps alternate: when the operator steps twice with one foot, the robot's other foot steps in between,
   towards its own latest target (counted in `extra_steps`). A placement beyond the limits (an operator's step
   longer than the robot's) is reached in more steps (`catch_up`, at most that many pairs): the other foot steps
   as far as its limits allow towards its place beside the target (the robot's stance width, the target's
   heading), then the foot steps again towards its target; the pairs are counted in `extra_steps` too. A robot
   that takes more steps than its operator falls behind in time (each step takes `single_support` +
   `double_support`), not in place. `catch_up: 0` clamps instead.
4. **Plan**: a `FootstepPlan` with the planner's uniform timing (`single_support`, `double_support`), not the
   operator's: a human steps every 0.4-0.6 s, TALOS' walks here take 0.9-1 s per step, so the robot's steps queue
   behind the operator's. Robot step i lifts off at ``T_init + i P`` with ``T_init`` the least time that keeps
   every lift-off at least `latency` after its operator step's touch-down (and at least the pattern generator's
   preview horizon plus its initial shift). The default latency, ``settle + max(0, preview_horizon -
   single_support)``, makes the offline plan causal: a step's placement is known (the foot down and settled)
   before the ZMP preview controller first looks at the support it makes. The ZMP preview control (Kajita 2003)
   then gives the CoM and DCM, quintic swings the feet (`planning.generate_walk`), as for the `walk` scenarios.

Metrics (`StepPlan.placements`): per operator step, the operator's scaled placement, the robot's planned one
(clamped) and the distance between them; the run's measured touch-downs are compared in the scenario's metrics.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from ...side import Side

__all__ = ["SteppingConfig", "StepPlan", "plan_operator_steps"]


@dataclass(frozen=True)
class SteppingConfig:
    """Timing and settings of the robot's steps (module docstring); durations [s], apex [m].

    `latency` None: ``settle + max(0, preview_horizon - single_support)`` (causal with the preview)."""

    single_support: float = 0.9
    double_support: float = 0.2
    final_double_support: float = 1.2
    preview_horizon: float = 1.2
    initial_shift: float = 0.8
    apex: float = 0.05
    latency: float | None = None
    settle: float = 0.15
    catch_up: int = 3

    def __post_init__(self) -> None:
        for name in ("single_support", "double_support", "final_double_support", "preview_horizon",
                     "initial_shift", "settle"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ConfigError(f"stepping.{name} must be > 0, got {v!r}", key=f"stepping.{name}")
        if self.latency is not None and not (np.isfinite(self.latency) and self.latency >= 0):
            raise ConfigError(f"stepping.latency must be >= 0 s, got {self.latency!r}", key="stepping.latency")
        if not (isinstance(self.catch_up, (int, np.integer)) and self.catch_up >= 0):
            raise ConfigError(f"stepping.catch_up must be an integer >= 0, got {self.catch_up!r}",
                              key="stepping.catch_up")

    @property
    def effective_latency(self) -> float:
        if self.latency is not None:
            return float(self.latency)
        return self.settle + max(0.0, self.preview_horizon - self.single_support)


@dataclass(frozen=True)
class StepPlan:
    """The robot's footstep plan made from the operator's steps.

    Attributes:
        plan: the `FootstepPlan` (initial feet, footsteps, timing, sole, limits).
        placements: per operator step, a dict: side, operator touch-down [s, run time], robot step index,
            target (x, y, yaw) the operator's scaled placement, planned (x, y, yaw) the clamped one, clamp_m the
            horizontal distance between them [m].
        extra_steps: robot steps in place inserted for the alternation.
        latency: the least delay of a robot lift-off after its operator step's touch-down [s] (None: no step).
        look_ahead: the longest time a step's placement is used by the preview before it is known (touch-down +
            settle) [s]; <= 0: the plan is causal (None: no step).
    """

    plan: object
    placements: tuple
    extra_steps: int
    latency: float
    look_ahead: float


#: a placement this close to its target is reached (no catch-up step) [m]
_REACHED = 1e-3


def _wrap(a: float) -> float:
    return float((a + np.pi) % (2.0 * np.pi) - np.pi)


def plan_operator_steps(steps, *, T_world_suit, proportion: float, feet_suit0: dict, feet0: dict, limits,
                        sole, config: SteppingConfig, time_offset: float = 0.0, speed: float = 1.0) -> StepPlan:
    """The robot's footstep plan for the operator's `steps` (module docstring).

    Args:
        steps: `OperatorStep`s in touch-down order (source time).
        T_world_suit: the calibration's suit -> robot world transform (`.rotation`, 3x3).
        proportion: the robot/human scale k.
        feet_suit0: side ("left"/"right") -> the operator's ankle (3,) at the calibration frame, suit world [m].
        feet0: Side -> the robot's initial sole `Footstep`.
        limits: the profile's `SteppingSpec` (max_forward, max_backward, max_lateral, max_turn, min_clearance).
        sole: `SoleRectangle`.
        time_offset: source time of run time 0 [s]; speed: playback factor (run time = (source - offset) / speed).
    """
    from ...planning import Footstep, FootstepPlan, ReachLimits, StepTiming
    from ...planning.geometry import polygons_penetration, rotation_from_yaw, yaw_of

    R = np.asarray(T_world_suit.rotation, dtype=float)
    k = float(proportion)
    feet = dict(feet0)
    yaw0 = {s: yaw_of(feet0[s].R_world_sole) for s in Side}
    p0 = {s: np.array(feet0[s].p_world_sole, dtype=float) for s in Side}
    sep = float(np.linalg.norm(p0[Side.LEFT][:2] - p0[Side.RIGHT][:2]))
    min_width = sole.width + limits.min_clearance
    max_width = sep + limits.max_lateral
    robot_steps: list = []   # Footsteps
    triggers: list = []      # per robot step: the run time of the operator touch-down it answers
    placements = []
    extra = 0
    last_side = None
    def place(side: Side, target_xy: np.ndarray, target_yaw: float):
        """`side`'s footstep towards the target, clamped in the stance sole's frame (module docstring)."""
        stance = feet[side.other]
        s_yaw = yaw_of(stance.R_world_sole)
        R2 = rotation_from_yaw(s_yaw)[:2, :2]  # the stance sole's heading in the ground plane
        rel = R2.T @ (target_xy - stance.p_world_sole[:2])
        dyaw = float(np.clip(_wrap(target_yaw - s_yaw), -limits.max_turn, limits.max_turn))
        dx = float(np.clip(rel[0], -limits.max_backward, limits.max_forward))
        dy = side.sign * float(np.clip(side.sign * rel[1], min_width, max_width))
        for _ in range(40):
            xy = stance.p_world_sole[:2] + R2 @ np.array([dx, dy])
            foot = Footstep.from_xyz_yaw(side, xy[0], xy[1], float(p0[side][2]), s_yaw + dyaw)
            depth = polygons_penetration(sole.footprint(foot.p_world_sole, foot.R_world_sole),
                                         sole.footprint(stance.p_world_sole, stance.R_world_sole))
            if depth <= 1e-9 or side.sign * dy >= max_width:
                break
            dy += side.sign * 0.01   # still overlapping (turned feet): outwards
        return foot

    targets = {s: (p0[s][:2].copy(), yaw0[s]) for s in Side}   # each foot's latest operator placement
    for st in steps:
        side = Side(st.side)
        t_td = (st.touch_down - time_offset) / speed
        if last_side is side:  # the other foot steps (towards its own target): the plan alternates
            other = side.other
            feet[other] = place(other, *targets[other])
            robot_steps.append(feet[other])
            triggers.append(t_td)
            extra += 1
        d = k * (R @ (np.asarray(st.p_suit, dtype=float) - np.asarray(feet_suit0[st.side], dtype=float)))
        target_xy = p0[side][:2] + d[:2]
        target_yaw = yaw0[side] + float(st.yaw)
        targets[side] = (target_xy, target_yaw)
        foot = feet[side] = place(side, target_xy, target_yaw)
        robot_steps.append(foot)
        triggers.append(t_td)
        for _ in range(config.catch_up):  # beyond the limits: the other foot past it, then this foot again
            if np.linalg.norm(foot.p_world_sole[:2] - target_xy) <= _REACHED:
                break
            other = side.other
            beside = target_xy + rotation_from_yaw(target_yaw)[:2, :2] @ np.array([0.0, other.sign * sep])
            feet[other] = place(other, beside, target_yaw)
            foot = feet[side] = place(side, target_xy, target_yaw)
            robot_steps += [feet[other], foot]
            triggers += [t_td, t_td]
            extra += 2
        last_side = side
        xy = foot.p_world_sole[:2]
        placements.append({"side": st.side, "operator_touch_down_s": float(t_td),
                           "robot_step": len(robot_steps) - 1,
                           "target": [float(target_xy[0]), float(target_xy[1]), float(target_yaw)],
                           "planned": [float(xy[0]), float(xy[1]), float(yaw_of(foot.R_world_sole))],
                           "clamp_m": float(np.linalg.norm(xy - target_xy))})
    cfg = config
    latency = cfg.effective_latency
    period = cfg.single_support + cfg.double_support
    t_init = cfg.preview_horizon + cfg.initial_shift
    for i, t_td in enumerate(triggers):
        t_init = max(t_init, t_td + latency - i * period)
    timing = StepTiming(cfg.single_support, cfg.double_support, t_init, cfg.final_double_support)
    reach = ReachLimits(max_length=max(limits.max_forward, limits.max_backward) + 1e-6,
                        max_width=max_width + 0.05, max_yaw=limits.max_turn + 1e-6)
    plan = FootstepPlan(initial_feet=dict(feet0), steps=tuple(robot_steps), timing=timing, sole=sole, limits=reach)
    # when each placement is first needed by the preview (touch-down - horizon) vs known (operator touch-down +
    # settle)
    look = max((t_td + cfg.settle - (plan.touch_down_time(i) - cfg.preview_horizon)
                for i, t_td in enumerate(triggers)), default=None)
    lat = min((plan.lift_off_time(i) - t_td for i, t_td in enumerate(triggers)), default=None)
    return StepPlan(plan, tuple(placements), extra, None if lat is None else float(lat),
                    None if look is None else float(look))
