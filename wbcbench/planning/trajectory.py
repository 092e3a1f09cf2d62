"""Time-indexed walking references: per-tick arrays plus `at(t)` / `sample(tick)` accessors.

Time is an integer tick counter, t = tick * dt (no accumulated floating-point time). `at(t)` picks the
nearest tick; past the end it returns the last tick (the plan ends at rest).
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from ..errors import PlanningError
from .geometry import SoleRectangle, support_polygon
from ..side import Side

if TYPE_CHECKING:  # pragma: no cover
    from .footsteps import FootstepPlan

__all__ = [
    "ContactEventKind",
    "ContactEvent",
    "ContactSchedule",
    "FootTrajectory",
    "FootSample",
    "WalkSample",
    "WalkTrajectory",
]


def _freeze(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    a.flags.writeable = False
    return a


class ContactEventKind(enum.Enum):
    """A foot leaving (LIFT_OFF) or reaching (TOUCH_DOWN) the ground."""

    LIFT_OFF = "lift_off"
    TOUCH_DOWN = "touch_down"


@dataclass(frozen=True)
class ContactEvent:
    """One contact change.

    Attributes:
        kind: lift-off or touch-down.
        side: the foot.
        tick: first tick of the new contact state (in the air from a lift-off tick, on the ground from a
            touch-down tick).
        time: tick * dt [s].
        step: index of the footstep in the plan.
    """

    kind: ContactEventKind
    side: Side
    tick: int
    time: float
    step: int


@dataclass(frozen=True, eq=False)
class ContactSchedule:
    """Which feet touch the ground at each tick.

    Attributes:
        dt: tick period [s].
        in_contact: Side -> bool array, shape (n,).
        events: lift-offs and touch-downs in time order.
    """

    dt: float
    in_contact: Mapping[Side, np.ndarray]
    events: tuple[ContactEvent, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "in_contact",
                           MappingProxyType({s: _freeze(np.asarray(v, bool)) for s, v in self.in_contact.items()}))

    @property
    def n_ticks(self) -> int:
        return len(self.in_contact[Side.LEFT])

    @property
    def double_support(self) -> np.ndarray:
        """True where both feet are on the ground, shape (n,)."""
        return self.in_contact[Side.LEFT] & self.in_contact[Side.RIGHT]

    def contact_sides(self, tick: int) -> tuple[Side, ...]:
        """The feet on the ground at a tick (LEFT first)."""
        return tuple(s for s in (Side.LEFT, Side.RIGHT) if self.in_contact[s][tick])

    def swing_side(self, tick: int) -> Side | None:
        """The foot in the air at a tick, None in double support."""
        for s in (Side.LEFT, Side.RIGHT):
            if not self.in_contact[s][tick]:
                return s
        return None


@dataclass(frozen=True, eq=False)
class FootSample:
    """One foot at one tick (world frame).

    Attributes:
        T_world_sole: pose, shape (4, 4).
        v_world_sole: linear velocity of the sole origin [m/s], shape (3,).
        w_world_sole: angular velocity [rad/s], shape (3,).
        a_world_sole: linear acceleration (derivative of v_world_sole) [m/s^2], shape (3,).
        dw_world_sole: angular acceleration [rad/s^2], shape (3,).
        in_contact: the foot is on the ground.
    """

    T_world_sole: np.ndarray
    v_world_sole: np.ndarray
    w_world_sole: np.ndarray
    a_world_sole: np.ndarray
    dw_world_sole: np.ndarray
    in_contact: bool

    @property
    def p_world_sole(self) -> np.ndarray:
        return self.T_world_sole[:3, 3]

    @property
    def R_world_sole(self) -> np.ndarray:
        return self.T_world_sole[:3, :3]


@dataclass(frozen=True, eq=False)
class FootTrajectory:
    """One foot over the whole plan, one row per tick (world frame).

    Attributes:
        side: the foot.
        p_world_sole: (n, 3) [m]. R_world_sole: (n, 3, 3).
        v_world_sole: (n, 3) [m/s]. w_world_sole: (n, 3) [rad/s].
        a_world_sole: (n, 3) [m/s^2]. dw_world_sole: (n, 3) [rad/s^2].
        in_contact: (n,) bool.
    """

    side: Side
    p_world_sole: np.ndarray
    R_world_sole: np.ndarray
    v_world_sole: np.ndarray
    w_world_sole: np.ndarray
    a_world_sole: np.ndarray
    dw_world_sole: np.ndarray
    in_contact: np.ndarray

    def __post_init__(self) -> None:
        for name in ("p_world_sole", "R_world_sole", "v_world_sole", "w_world_sole", "a_world_sole",
                     "dw_world_sole", "in_contact"):
            object.__setattr__(self, name, _freeze(getattr(self, name)))

    def T_world_sole(self, tick: int) -> np.ndarray:
        """Pose at a tick, shape (4, 4)."""
        T = np.eye(4)
        T[:3, :3] = self.R_world_sole[tick]
        T[:3, 3] = self.p_world_sole[tick]
        return T

    def sample(self, tick: int) -> FootSample:
        return FootSample(self.T_world_sole(tick), self.v_world_sole[tick].copy(), self.w_world_sole[tick].copy(),
                          self.a_world_sole[tick].copy(), self.dw_world_sole[tick].copy(),
                          bool(self.in_contact[tick]))


@dataclass(frozen=True, eq=False)
class WalkSample:
    """All walking references at one tick (world frame).

    Attributes:
        tick: tick index. t: tick * dt [s].
        p_world_com, v_world_com, a_world_com: CoM position [m], velocity [m/s], acceleration [m/s^2], (3,).
        p_world_zmp_ref: planned ZMP [m], (3,) (z: the support height).
        p_world_zmp: ZMP of the planned CoM through the cart-table model [m], (3,).
        p_world_dcm: DCM xi = c + c_dot / omega [m], (3,).
        feet: Side -> FootSample.
    """

    tick: int
    t: float
    p_world_com: np.ndarray
    v_world_com: np.ndarray
    a_world_com: np.ndarray
    p_world_zmp_ref: np.ndarray
    p_world_zmp: np.ndarray
    p_world_dcm: np.ndarray
    feet: Mapping[Side, FootSample]

    def contact_sides(self) -> tuple[Side, ...]:
        return tuple(s for s in (Side.LEFT, Side.RIGHT) if self.feet[s].in_contact)


@dataclass(frozen=True, eq=False)
class WalkTrajectory:
    """A walking pattern sampled at every tick; rows are ticks, t = tick * dt.

    Attributes:
        dt: tick period [s]. com_height: c_z above the support [m]. gravity: [m/s^2].
        omega: sqrt(gravity / com_height) [1/s].
        p_world_com, v_world_com, a_world_com: CoM, (n, 3) [m], [m/s], [m/s^2].
        p_world_zmp_ref: planned ZMP, (n, 3) [m]; z is the support height.
        p_world_zmp: ZMP of the CoM through the cart-table model, (n, 3) [m]:
            p_xy = c_xy - com_height / gravity * c_ddot_xy, z as p_world_zmp_ref.
        p_world_dcm: DCM xi = c + c_dot / omega (paper Eq. 2), (n, 3) [m].
        feet: Side -> FootTrajectory.
        contacts: the contact schedule.
        sole: the contact rectangle (for support polygons).
        plan: the footstep plan this was generated from.
    """

    dt: float
    com_height: float
    gravity: float
    omega: float
    p_world_com: np.ndarray
    v_world_com: np.ndarray
    a_world_com: np.ndarray
    p_world_zmp_ref: np.ndarray
    p_world_zmp: np.ndarray
    p_world_dcm: np.ndarray
    feet: Mapping[Side, FootTrajectory]
    contacts: ContactSchedule
    sole: SoleRectangle
    plan: "FootstepPlan"

    def __post_init__(self) -> None:
        for name in ("p_world_com", "v_world_com", "a_world_com", "p_world_zmp_ref", "p_world_zmp", "p_world_dcm"):
            object.__setattr__(self, name, _freeze(getattr(self, name)))
        object.__setattr__(self, "feet", MappingProxyType(dict(self.feet)))

    @property
    def n_ticks(self) -> int:
        """Number of ticks, the last at t = (n - 1) dt."""
        return len(self.p_world_com)

    @property
    def duration(self) -> float:
        """Time of the last tick [s]."""
        return (self.n_ticks - 1) * self.dt

    @property
    def t(self) -> np.ndarray:
        """Tick times, shape (n,) [s]."""
        return np.arange(self.n_ticks) * self.dt

    def tick_at(self, t: float) -> int:
        """Nearest tick to time t [s], clamped to the last tick. Raises ValueError for t < 0."""
        if not np.isfinite(t) or t < -0.5 * self.dt:
            raise PlanningError(f"time must be >= 0, got {t!r}")
        return min(int(round(t / self.dt)), self.n_ticks - 1)

    def sample(self, tick: int) -> WalkSample:
        """All references at a tick (0 <= tick < n_ticks)."""
        if not 0 <= tick < self.n_ticks:
            raise IndexError(f"tick {tick} out of range 0..{self.n_ticks - 1}")
        return WalkSample(tick, tick * self.dt, self.p_world_com[tick].copy(), self.v_world_com[tick].copy(),
                          self.a_world_com[tick].copy(), self.p_world_zmp_ref[tick].copy(),
                          self.p_world_zmp[tick].copy(), self.p_world_dcm[tick].copy(),
                          MappingProxyType({s: f.sample(tick) for s, f in self.feet.items()}))

    def at(self, t: float) -> WalkSample:
        """All references at time t [s] (nearest tick; the last tick after the end)."""
        return self.sample(self.tick_at(t))

    def support_polygon(self, tick: int) -> np.ndarray:
        """Convex hull of the footprints of the feet in contact at a tick, shape (k, 2) [m], counter-clockwise."""
        prints = [self.sole.footprint(f.p_world_sole[tick], f.R_world_sole[tick])
                  for s, f in self.feet.items() if f.in_contact[tick]]
        return support_polygon(prints)
