"""Footstep plans: where each foot goes and when, validated before anything runs.

A plan is the initial pose of both soles, a sequence of footsteps (one foot moves per step) and a uniform
timing. Timeline, with n steps (t = 0 at the start of the plan):

    [0, T_init)                       initial double support
    step i, i = 0..n-1:
        [t_lo(i), t_td(i))            single support: step i's foot swings, t_lo(i) = T_init + i (T_ss + T_ds)
        [t_td(i), t_td(i) + T_ds)     double support (after the last step: the final double support T_final)
                                      t_td(i) = t_lo(i) + T_ss

Generators build plans from a walking frame (the pose midway between the feet) that moves by a fixed
increment per step, the moving foot being placed at +-foot_separation / 2 across that frame:
`straight_walk` (forward steps, optionally up or down by `step_height` per step: stairs), `lateral_walk`
(the leading foot steps out, the trailing foot closes) and `turning_walk` (the frame turns by `yaw_per_step`).

"Step length" is the distance the walking frame advances per step, which is also the forward distance of the
new foot ahead of the stance foot. Six steps of 0.20 m plus a final step travel 1.2 m (the paper's 20 cm walk).

Validation (ValueError naming the step, the feet and the limit): overlapping footprints, steps beyond reach
(relative to the stance foot: forward, lateral, height, yaw), feet crossing, non-positive durations.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from ..errors import PlanningError
from .geometry import SoleRectangle, polygons_penetration, rotation_from_yaw, so3_log, yaw_of
from ..side import Side

__all__ = [
    "Footstep",
    "StepTiming",
    "ReachLimits",
    "FootstepPlan",
    "StepIncrement",
    "footsteps_from_increments",
    "straight_walk",
    "lateral_walk",
    "turning_walk",
]


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class Footstep:
    """Pose of one sole frame on the ground.

    Attributes:
        side: which foot.
        p_world_sole: sole frame origin in the world, shape (3,) [m].
        R_world_sole: sole frame orientation, shape (3, 3); its z axis (the contact normal) must point up.
    """

    side: Side
    p_world_sole: np.ndarray
    R_world_sole: np.ndarray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self) -> None:
        if not isinstance(self.side, Side):
            object.__setattr__(self, "side", Side.parse(self.side))
        p = np.asarray(self.p_world_sole, dtype=float)
        R = np.asarray(self.R_world_sole, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise PlanningError(f"Footstep ({self.side}): p_world_sole must be 3 finite numbers [m], got {p!r}")
        if R.shape != (3, 3) or not np.all(np.isfinite(R)):
            raise PlanningError(f"Footstep ({self.side}): R_world_sole must be a finite 3x3 matrix, got {R!r}")
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0.0:
            raise PlanningError(f"Footstep ({self.side}): R_world_sole is not a rotation matrix")
        if R[2, 2] <= 0.0:
            raise PlanningError(f"Footstep ({self.side}): the sole normal (z axis of R_world_sole) must point up")
        object.__setattr__(self, "p_world_sole", _readonly(p))
        object.__setattr__(self, "R_world_sole", _readonly(R))

    @classmethod
    def from_xyz_yaw(cls, side: Side, x: float, y: float, z: float = 0.0, yaw: float = 0.0) -> "Footstep":
        """A flat footstep at (x, y, z) [m] with heading `yaw` [rad]."""
        return cls(side, np.array([x, y, z], float), rotation_from_yaw(yaw))

    @property
    def yaw(self) -> float:
        """Heading of the sole x axis [rad]."""
        return yaw_of(self.R_world_sole)

    @property
    def T_world_sole(self) -> np.ndarray:
        """Homogeneous transform, shape (4, 4)."""
        T = np.eye(4)
        T[:3, :3] = self.R_world_sole
        T[:3, 3] = self.p_world_sole
        return T

    def in_frame_of(self, other: "Footstep") -> tuple[np.ndarray, float]:
        """This sole's position in `other`'s sole frame, shape (3,) [m], and the rotation angle between them [rad]."""
        p = other.R_world_sole.T @ (self.p_world_sole - other.p_world_sole)
        angle = float(np.linalg.norm(so3_log(other.R_world_sole.T @ self.R_world_sole)))
        return p, angle

    def moved_to(self, p_world_sole: np.ndarray, R_world_sole: np.ndarray) -> "Footstep":
        """The same foot at another pose."""
        return Footstep(self.side, p_world_sole, R_world_sole)


def _positive_duration(owner: str, name: str, value: float) -> None:
    if not isinstance(value, (int, float, np.floating, np.integer)) or not np.isfinite(value) or value <= 0.0:
        raise PlanningError(f"{owner}.{name} must be a positive duration in seconds, got {value!r}")


@dataclass(frozen=True)
class StepTiming:
    """Durations of a walk [s], all > 0.

    Attributes:
        single_support: one foot swings (paper, 20 cm walk: 0.9; fast: 0.711).
        double_support: both feet on the ground between two steps (paper: 0.115; fast: 0.089).
        initial_double_support: standing before the first lift-off. The pattern generator holds the ZMP at
            the initial CoM for longer than its preview horizon inside this phase, then shifts it to the
            first stance foot; it tells you if this is too short (default 3.5 s = 2.5 s horizon + 0.8 s
            shift + margin).
        final_double_support: standing after the last touch-down while the CoM settles between the feet
            (default 3.0 s: the CoM ends within 1 mm and 1 mm/s of the feet midpoint).
    """

    single_support: float
    double_support: float
    initial_double_support: float = 3.5
    final_double_support: float = 3.0

    def __post_init__(self) -> None:
        for name in ("single_support", "double_support", "initial_double_support", "final_double_support"):
            _positive_duration("StepTiming", name, getattr(self, name))

    @property
    def step_period(self) -> float:
        """Single plus double support [s]."""
        return self.single_support + self.double_support


@dataclass(frozen=True)
class ReachLimits:
    """How far a foot may land from the stance foot, measured in the stance sole frame.

    Attributes:
        max_length: |forward/backward offset| [m]; the 60 cm walk needs 0.6.
        max_width: |lateral offset| between the soles [m].
        max_height: |height change| [m].
        max_yaw: rotation angle between the two soles [rad].
    """

    max_length: float = 0.65
    max_width: float = 0.45
    max_height: float = 0.25
    max_yaw: float = 0.8

    def __post_init__(self) -> None:
        for name in ("max_length", "max_width", "max_height", "max_yaw"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0.0:
                raise PlanningError(f"ReachLimits.{name} must be positive, got {value!r}")


@dataclass(frozen=True, eq=False)
class FootstepPlan:
    """Initial feet, footsteps and timing, validated on construction.

    Attributes:
        initial_feet: pose of each sole at t = 0 (a read-only mapping Side -> Footstep, both sides).
        steps: the footsteps in order; step i moves foot `steps[i].side` to `steps[i]`.
        timing: the durations.
        sole: the contact rectangle of each foot (used for overlap checks and support polygons).
        limits: reach limits the steps are checked against.

    Raises:
        ValueError: feet overlapping, a step beyond reach or crossing over the stance foot, bad inputs.
    """

    initial_feet: Mapping[Side, Footstep]
    steps: tuple[Footstep, ...]
    timing: StepTiming
    sole: SoleRectangle
    limits: ReachLimits = field(default_factory=ReachLimits)

    def __post_init__(self) -> None:
        try:
            feet = {Side.parse(k): v for k, v in dict(self.initial_feet).items()}
        except ValueError as exc:
            raise PlanningError(f"FootstepPlan.initial_feet: {exc}") from None
        if set(feet) != {Side.LEFT, Side.RIGHT} or len(self.initial_feet) != 2:
            raise PlanningError(f"FootstepPlan.initial_feet needs exactly the sides left and right, got "
                             f"{sorted(str(s) for s in feet)}")
        for side, foot in feet.items():
            if not isinstance(foot, Footstep) or foot.side is not side:
                raise PlanningError(f"FootstepPlan.initial_feet[{side}] must be a Footstep of side {side}")
        object.__setattr__(self, "initial_feet", MappingProxyType(feet))
        steps = tuple(self.steps)
        for i, step in enumerate(steps):
            if not isinstance(step, Footstep):
                raise PlanningError(f"FootstepPlan.steps[{i}] must be a Footstep, got {type(step).__name__}")
        object.__setattr__(self, "steps", steps)
        if not isinstance(self.timing, StepTiming):
            raise PlanningError("FootstepPlan.timing must be a StepTiming")
        if not isinstance(self.sole, SoleRectangle):
            raise PlanningError("FootstepPlan.sole must be a SoleRectangle")
        self._validate()

    # ---- validation -------------------------------------------------------------------------------
    def _check_pair(self, what: str, moving: Footstep, stance: Footstep) -> None:
        depth = polygons_penetration(self.sole.footprint(moving.p_world_sole, moving.R_world_sole),
                                     self.sole.footprint(stance.p_world_sole, stance.R_world_sole))
        if depth > 1e-9:
            raise PlanningError(f"{what}: the {moving.side} footprint overlaps the {stance.side} foot by "
                             f"{depth:.4f} m (sole {self.sole.length} x {self.sole.width} m); "
                             "increase the foot separation or reduce the yaw")
        p, angle = moving.in_frame_of(stance)
        lim = self.limits
        if abs(p[0]) > lim.max_length + 1e-12:
            raise PlanningError(f"{what}: the {moving.side} foot lands {p[0]:+.3f} m forward of the {stance.side} "
                             f"(stance) foot, beyond max_length {lim.max_length} m")
        if abs(p[1]) > lim.max_width + 1e-12:
            raise PlanningError(f"{what}: the {moving.side} foot lands {abs(p[1]):.3f} m sideways from the "
                             f"{stance.side} (stance) foot, beyond max_width {lim.max_width} m")
        if moving.side.sign * p[1] <= 0.0:
            raise PlanningError(f"{what}: the {moving.side} foot crosses over the {stance.side} (stance) foot "
                             f"(lateral offset {p[1]:+.3f} m in the stance sole frame; a {moving.side} foot "
                             f"must be on its {moving.side} side)")
        if abs(p[2]) > lim.max_height + 1e-12:
            raise PlanningError(f"{what}: the {moving.side} foot lands {p[2]:+.3f} m above the {stance.side} "
                             f"(stance) foot, beyond max_height {lim.max_height} m")
        if angle > lim.max_yaw + 1e-12:
            raise PlanningError(f"{what}: the {moving.side} foot is turned {angle:.3f} rad from the {stance.side} "
                             f"(stance) foot, beyond max_yaw {lim.max_yaw} rad")

    def _validate(self) -> None:
        feet = dict(self.initial_feet)
        self._check_pair("initial feet", feet[Side.LEFT], feet[Side.RIGHT])
        for i, step in enumerate(self.steps):
            stance = feet[step.side.other]
            self._check_pair(f"step {i} ({step.side} foot)", step, stance)
            feet[step.side] = step

    # ---- queries ----------------------------------------------------------------------------------
    @property
    def n_steps(self) -> int:
        """Number of footsteps."""
        return len(self.steps)

    @property
    def duration(self) -> float:
        """Total duration of the plan [s]."""
        t = self.timing
        if not self.steps:
            return t.initial_double_support + t.final_double_support
        return self.touch_down_time(self.n_steps - 1) + t.final_double_support

    def lift_off_time(self, i: int) -> float:
        """Time step i's foot leaves the ground [s]."""
        self._check_index(i)
        return self.timing.initial_double_support + i * self.timing.step_period

    def touch_down_time(self, i: int) -> float:
        """Time step i's foot lands [s]."""
        return self.lift_off_time(i) + self.timing.single_support

    def feet_before(self, i: int) -> dict[Side, Footstep]:
        """Both feet just before step i lifts off (i = n_steps gives the final feet)."""
        if not 0 <= i <= self.n_steps:
            raise IndexError(f"step index {i} out of range 0..{self.n_steps}")
        feet = dict(self.initial_feet)
        for step in self.steps[:i]:
            feet[step.side] = step
        return feet

    def stance_foot(self, i: int) -> Footstep:
        """The foot on the ground during step i's single support."""
        self._check_index(i)
        return self.feet_before(i)[self.steps[i].side.other]

    @property
    def final_feet(self) -> dict[Side, Footstep]:
        """Both feet after the last step."""
        return self.feet_before(self.n_steps)

    def _check_index(self, i: int) -> None:
        if not 0 <= i < self.n_steps:
            raise IndexError(f"step index {i} out of range 0..{self.n_steps - 1}")


@dataclass(frozen=True)
class StepIncrement:
    """Motion of the walking frame for one step, expressed in the walking frame before the step.

    Attributes:
        dx: forward [m]. dy: leftward [m]. dz: up [m]. dyaw: turn, counter-clockwise [rad].
    """

    dx: float = 0.0
    dy: float = 0.0
    dz: float = 0.0
    dyaw: float = 0.0

    def __post_init__(self) -> None:
        for name in ("dx", "dy", "dz", "dyaw"):
            if not np.isfinite(getattr(self, name)):
                raise PlanningError(f"StepIncrement.{name} must be finite, got {getattr(self, name)!r}")


def _count(n_steps: int) -> int:
    if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 0:
        raise PlanningError(f"n_steps must be a non-negative integer, got {n_steps!r}")
    return int(n_steps)


def _separation(foot_separation: float) -> float:
    if not np.isfinite(foot_separation) or foot_separation <= 0.0:
        raise PlanningError(f"foot_separation must be a positive distance in metres, got {foot_separation!r}")
    return float(foot_separation)


def footsteps_from_increments(
    increments: Sequence[StepIncrement],
    *,
    first_side: Side,
    foot_separation: float,
    timing: StepTiming,
    sole: SoleRectangle,
    start: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
    limits: ReachLimits | None = None,
) -> FootstepPlan:
    """The general generator: one footstep per increment, sides alternating from `first_side`.

    The walking frame starts at `start` = (x, y, z [m], yaw [rad]) with the soles at +-foot_separation / 2
    across it; before step k it moves by increments[k] (in its own frame) and step k's foot lands at
    +-foot_separation / 2 across the moved frame, with the frame's heading and height.

    Args:
        increments: walking-frame motion per step.
        first_side: the foot that moves first.
        foot_separation: lateral distance between the sole frames at rest [m] (TALOS: 2 x 0.0857).
        timing, sole, limits: as in FootstepPlan.
        start: walking frame at t = 0.

    Raises:
        ValueError: as FootstepPlan.
    """
    sep = _separation(foot_separation)
    first_side = Side.parse(first_side)
    if len(start) != 4 or not np.all(np.isfinite(start)):
        raise PlanningError(f"start must be 4 finite numbers (x, y, z [m], yaw [rad]), got {start!r}")
    x, y, z, yaw = (float(v) for v in start)

    def foot(side: Side) -> Footstep:
        off = rotation_from_yaw(yaw) @ np.array([0.0, side.sign * 0.5 * sep, 0.0])
        return Footstep(side, np.array([x, y, z]) + off, rotation_from_yaw(yaw))

    initial = {Side.LEFT: foot(Side.LEFT), Side.RIGHT: foot(Side.RIGHT)}
    steps = []
    side = first_side
    for inc in increments:
        if not isinstance(inc, StepIncrement):
            raise PlanningError(f"increments must be StepIncrement, got {type(inc).__name__}")
        c, s = np.cos(yaw), np.sin(yaw)
        x, y, z, yaw = x + c * inc.dx - s * inc.dy, y + s * inc.dx + c * inc.dy, z + inc.dz, yaw + inc.dyaw
        steps.append(foot(side))
        side = side.other
    return FootstepPlan(initial, tuple(steps), timing, sole, limits if limits is not None else ReachLimits())


def straight_walk(
    n_steps: int,
    step_length: float,
    *,
    foot_separation: float,
    timing: StepTiming,
    sole: SoleRectangle,
    step_height: float = 0.0,
    first_side: Side = Side.RIGHT,
    final_step: bool = True,
    start: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
    limits: ReachLimits | None = None,
) -> FootstepPlan:
    """Walk forward (or backward, step_length < 0): n_steps steps, then a final step bringing the feet together.

    Step k's foot lands (k + 1) * step_length ahead of the start and (k + 1) * step_height higher (stairs:
    one stair per step). The final step puts the other foot beside it. The paper's 20 cm walk is
    `straight_walk(6, 0.20, ...)` (1.2 m travelled); its 60 cm walk `straight_walk(6, 0.60, ...)`.

    Args:
        n_steps: number of steps before the final step (>= 0).
        step_length: forward advance per step [m].
        step_height: height change per step [m].
        first_side: the foot that moves first.
        final_step: append the step that brings the feet side by side.
        Others: as `footsteps_from_increments`.
    """
    n = _count(n_steps)
    if not np.isfinite(step_length) or not np.isfinite(step_height):
        raise PlanningError("step_length and step_height must be finite")
    incs = [StepIncrement(dx=step_length, dz=step_height)] * n
    if final_step and n > 0:
        incs.append(StepIncrement())
    return footsteps_from_increments(incs, first_side=first_side, foot_separation=foot_separation,
                                     timing=timing, sole=sole, start=start, limits=limits)


def lateral_walk(
    n_steps: int,
    lateral_step: float,
    *,
    foot_separation: float,
    timing: StepTiming,
    sole: SoleRectangle,
    start: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
    limits: ReachLimits | None = None,
) -> FootstepPlan:
    """Walk sideways: n_steps times, the leading foot steps out by |lateral_step| and the trailing foot follows.

    The leading foot is LEFT for lateral_step > 0 (walking left), RIGHT otherwise. The plan has 2 n_steps
    footsteps; the feet are side by side at the end, |lateral_step| * n_steps from the start.
    """
    n = _count(n_steps)
    if not np.isfinite(lateral_step) or lateral_step == 0.0:
        raise PlanningError(f"lateral_step must be a non-zero distance in metres, got {lateral_step!r}")
    leading = Side.LEFT if lateral_step > 0.0 else Side.RIGHT
    incs = [StepIncrement(dy=lateral_step), StepIncrement()] * n
    return footsteps_from_increments(incs, first_side=leading, foot_separation=foot_separation,
                                     timing=timing, sole=sole, start=start, limits=limits)


def turning_walk(
    n_steps: int,
    yaw_per_step: float,
    *,
    foot_separation: float,
    timing: StepTiming,
    sole: SoleRectangle,
    step_length: float = 0.0,
    first_side: Side | None = None,
    final_step: bool = True,
    start: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
    limits: ReachLimits | None = None,
) -> FootstepPlan:
    """Turn (in place or along an arc): per step the walking frame advances step_length, then turns yaw_per_step.

    The first foot defaults to the inside of the turn (LEFT for yaw_per_step > 0), which opens the feet
    instead of closing the toes. A final step brings the other foot beside the last one.

    Args:
        yaw_per_step: heading change per step [rad], counter-clockwise positive.
        step_length: forward advance per step [m].
        Others: as `straight_walk`.
    """
    n = _count(n_steps)
    if not np.isfinite(yaw_per_step) or not np.isfinite(step_length):
        raise PlanningError("yaw_per_step and step_length must be finite")
    if first_side is None:
        first_side = Side.LEFT if yaw_per_step >= 0.0 else Side.RIGHT
    incs = [StepIncrement(dx=step_length, dyaw=yaw_per_step)] * n
    if final_step and n > 0:
        incs.append(StepIncrement())
    return footsteps_from_increments(incs, first_side=first_side, foot_separation=foot_separation,
                                     timing=timing, sole=sole, start=start, limits=limits)
