"""Footsteps from a velocity command (vx, vy, yaw rate over time) or from a path of waypoints (x, y, yaw).

Both reduce to one loop: a target pose of the walking frame (the pose midway between the feet) per step, and a
step that moves the walking frame towards it as far as the robot's step limits allow (`StepLimits`, from the
robot profile's `stepping` section):

- forward / backward advance: both feet, clipped to max_forward / max_backward [m];
- sideways advance: only when the moving foot is the leading one (a left step when going left), clipped to
  max_lateral [m]; the trailing foot then closes (zero sideways advance), so the feet never cross;
- turn: only when the moving foot is the inside one (a left step when turning left), clipped to max_turn [rad];
  the outside foot then closes, parallel again, so the toes never close on each other;
- foot collision: the step's turn, then its sideways advance, is halved until both footprints, grown by
  min_clearance / 2 each, do not overlap.

A velocity command's target for step k is the command integrated (in the walking frame, from the end of the
initial double support) up to the end of step k's period (keyframes at the start that do not move the frame are
skipped: the robot stands until the command moves); a path's target is its next waypoint not yet reached. When the
target no longer moves, the loop steps until the frame is there, then one step brings the feet side by side.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..side import Side
from .footsteps import FootstepPlan, ReachLimits, StepIncrement, StepTiming, footsteps_from_increments
from .geometry import SoleRectangle, polygons_penetration, rotation_from_yaw

__all__ = ["StepLimits", "VelocityCommand", "plan_from_command", "plan_from_path"]

_POS_TOL = 1e-3      # [m] the walking frame is at its target
_YAW_TOL = 1e-3      # [rad]
MAX_STEPS = 400
"""Safety bound on the number of footsteps of one plan."""


@dataclass(frozen=True)
class StepLimits:
    """Per-step motion of the walking frame (see the module docstring); all > 0 except min_clearance >= 0.

    Attributes:
        max_forward, max_backward: advance [m]. max_lateral: sideways advance of the leading foot [m].
        max_turn: turn of the inside foot [rad]. min_clearance: least gap between the footprints [m].
    """

    max_forward: float
    max_backward: float
    max_lateral: float
    max_turn: float
    min_clearance: float = 0.0

    def __post_init__(self) -> None:
        for name in ("max_forward", "max_backward", "max_lateral", "max_turn"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0.0:
                raise ValueError(f"StepLimits.{name} must be positive, got {v!r}")
        if not np.isfinite(self.min_clearance) or self.min_clearance < 0.0:
            raise ValueError(f"StepLimits.min_clearance must be >= 0, got {self.min_clearance!r}")

    @classmethod
    def from_profile(cls, spec) -> "StepLimits":
        """From a robot profile's `SteppingSpec`."""
        return cls(spec.max_forward, spec.max_backward, spec.max_lateral, spec.max_turn, spec.min_clearance)

    def reach(self, foot_separation: float) -> ReachLimits:
        """Reach limits that every step this planner makes satisfies (relative to the stance foot)."""
        s = np.sin(self.max_turn)
        return ReachLimits(max_length=max(self.max_forward, self.max_backward) + foot_separation * s + 1e-6,
                           max_width=foot_separation + self.max_lateral + self.max_forward * s + 1e-6,
                           max_yaw=self.max_turn + 1e-6)


@dataclass(frozen=True, eq=False)
class VelocityCommand:
    """A walking-frame velocity over time, piecewise linear between keyframes.

    Attributes:
        t: keyframe times [s], shape (n,), strictly increasing from 0; the command ends at t[-1].
        velocity: (vx, vy, yaw rate) at each keyframe, shape (n, 3) [m/s, m/s, rad/s], in the walking frame
            (x forward, y left, counter-clockwise turn).
    """

    t: np.ndarray
    velocity: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        v = np.asarray(self.velocity, dtype=float)
        if t.ndim != 1 or len(t) < 2 or v.shape != (len(t), 3):
            raise ValueError(f"a velocity command needs at least 2 keyframes [t, vx, vy, yaw_rate], got times "
                             f"{t.shape} and velocities {v.shape}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise ValueError("a velocity command's keyframes must be finite numbers")
        if t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
            raise ValueError(f"a velocity command's times must start at 0 and increase strictly, got {t.tolist()}")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "velocity", v)

    @classmethod
    def from_rows(cls, rows) -> "VelocityCommand":
        """From rows [t, vx, vy, yaw_rate]."""
        a = np.asarray(rows, dtype=float)
        if a.ndim != 2 or a.shape[1] != 4:
            raise ValueError(f"velocity command rows must be [t, vx, vy, yaw_rate], got shape {a.shape}")
        return cls(a[:, 0], a[:, 1:])

    @classmethod
    def from_csv(cls, path: str | Path) -> "VelocityCommand":
        """From a CSV file with the header t,vx,vy,yaw_rate [s, m/s, m/s, rad/s]."""
        path = Path(path)
        try:
            with path.open(newline="") as f:
                reader = csv.DictReader(f)
                cols = ["t", "vx", "vy", "yaw_rate"]
                if reader.fieldnames is None or [c.strip() for c in reader.fieldnames] != cols:
                    raise ValueError(f"{path}: the header must be {','.join(cols)}, got {reader.fieldnames}")
                rows = [[float(r[c]) for c in reader.fieldnames] for r in reader]
        except OSError as exc:
            raise ValueError(f"{path}: cannot read the velocity command ({exc.strerror})") from None
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{path}: {exc}") from None
        return cls.from_rows(rows)

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def at(self, t: float) -> np.ndarray:
        """(vx, vy, yaw rate) at time t; zero outside [0, duration]."""
        if t < 0.0 or t > self.duration:
            return np.zeros(3)
        return np.array([np.interp(t, self.t, self.velocity[:, i]) for i in range(3)])

    def poses(self, times: np.ndarray, dt: float = 1e-3) -> np.ndarray:
        """Walking-frame pose (x, y, yaw) [m, m, rad] at each of `times`, integrated from (0, 0, 0) at t = 0,
        shape (len(times), 3)."""
        times = np.asarray(times, dtype=float)
        grid = np.arange(0.0, max(self.duration, float(times.max(initial=0.0))) + dt, dt)
        v = np.stack([np.interp(grid, self.t, self.velocity[:, i], right=0.0) for i in range(3)], axis=1)
        yaw = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:, 2] + v[:-1, 2]) * dt)])
        c, s = np.cos(yaw), np.sin(yaw)
        vxw, vyw = c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1]
        x = np.concatenate([[0.0], np.cumsum(0.5 * (vxw[1:] + vxw[:-1]) * dt)])
        y = np.concatenate([[0.0], np.cumsum(0.5 * (vyw[1:] + vyw[:-1]) * dt)])
        return np.stack([np.interp(times, grid, a) for a in (x, y, yaw)], axis=1)


def _feet_at(frame: np.ndarray, sep: float) -> dict[Side, tuple[np.ndarray, np.ndarray]]:
    R = rotation_from_yaw(frame[3])
    return {s: (frame[:3] + R @ np.array([0.0, s.sign * 0.5 * sep, 0.0]), R) for s in Side}


class _Stepper:
    """Moves the walking frame towards targets, one clipped step at a time (module docstring)."""

    def __init__(self, start: tuple[float, float, float, float], first_side: Side, sep: float,
                 limits: StepLimits, sole: SoleRectangle):
        self.frame = np.array(start, dtype=float)
        self.side = first_side
        self.sep = sep
        self.limits = limits
        c = limits.min_clearance
        self.grown = SoleRectangle(sole.length + c, sole.width + c, sole.center_x, sole.center_y)
        self.feet = _feet_at(self.frame, sep)
        self.increments: list[StepIncrement] = []

    def remaining(self, target: np.ndarray) -> np.ndarray:
        """Target (x, y, yaw) in the current walking frame."""
        d = rotation_from_yaw(self.frame[3]).T @ np.array([target[0] - self.frame[0], target[1] - self.frame[1], 0])
        return np.array([d[0], d[1], target[2] - self.frame[3]])

    def _collides(self, inc: StepIncrement) -> bool:
        frame = self._moved(inc)
        p, R = _feet_at(frame, self.sep)[self.side]
        q, Q = self.feet[self.side.other]
        return polygons_penetration(self.grown.footprint(p, R), self.grown.footprint(q, Q)) > 1e-9

    def _moved(self, inc: StepIncrement) -> np.ndarray:
        x, y, z, yaw = self.frame
        c, s = np.cos(yaw), np.sin(yaw)
        return np.array([x + c * inc.dx - s * inc.dy, y + s * inc.dx + c * inc.dy, z, yaw + inc.dyaw])

    def step_towards(self, target: np.ndarray) -> StepIncrement:
        lim, sign = self.limits, self.side.sign
        dx, dy, dyaw = self.remaining(target)
        dx = float(np.clip(dx, -lim.max_backward, lim.max_forward))
        dy = float(np.clip(dy, -lim.max_lateral, lim.max_lateral)) if dy * sign > 0.0 else 0.0
        dyaw = float(np.clip(dyaw, -lim.max_turn, lim.max_turn)) if dyaw * sign > 0.0 else 0.0
        inc = StepIncrement(dx, dy, 0.0, dyaw)
        for _ in range(12):
            if not self._collides(inc):
                break
            inc = StepIncrement(dx, dy if inc.dyaw else inc.dy * 0.5, 0.0, inc.dyaw * 0.5)
        else:
            raise ValueError(f"step {len(self.increments)}: no collision-free placement for the {self.side} foot "
                             f"(foot separation {self.sep:.3f} m, min_clearance {lim.min_clearance} m)")
        self.frame = self._moved(inc)
        self.feet[self.side] = _feet_at(self.frame, self.sep)[self.side]
        self.increments.append(inc)
        self.side = self.side.other
        return inc

    def arrived(self, target: np.ndarray) -> bool:
        r = self.remaining(target)
        return bool(np.hypot(r[0], r[1]) < _POS_TOL and abs(r[2]) < _YAW_TOL)

    def finish(self, target: np.ndarray) -> None:
        """Step until the frame is at `target` and the feet side by side."""
        while True:
            if len(self.increments) > MAX_STEPS:
                raise ValueError(f"more than {MAX_STEPS} footsteps: the target is out of reach of the step limits")
            if self.arrived(target):
                last = self.increments[-1] if self.increments else None
                if last is None or (last.dx, last.dy, last.dyaw) == (0.0, 0.0, 0.0):
                    return
            self.step_towards(target)


def _first_side(move: np.ndarray) -> Side:
    """The leading foot for a first move (x, y, yaw): the inside of a turn, else the side moved towards."""
    if abs(move[2]) > _YAW_TOL:
        return Side.LEFT if move[2] > 0.0 else Side.RIGHT
    if abs(move[1]) > _POS_TOL:
        return Side.LEFT if move[1] > 0.0 else Side.RIGHT
    return Side.RIGHT


def _world(start: tuple[float, float, float, float], rel: np.ndarray) -> np.ndarray:
    c, s = np.cos(start[3]), np.sin(start[3])
    return np.array([start[0] + c * rel[0] - s * rel[1], start[1] + s * rel[0] + c * rel[1], start[3] + rel[2]])


def plan_from_command(command: VelocityCommand, *, foot_separation: float, timing: StepTiming,
                      sole: SoleRectangle, limits: StepLimits,
                      start: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)) -> FootstepPlan:
    """Footsteps following a velocity command (module docstring); the command starts at the first lift-off.

    Args:
        command: the walking-frame velocity over time.
        foot_separation: lateral distance between the sole frames [m].
        timing: step durations; step k's target is the command's pose at (k + 1) step periods.
        sole, limits: footprint and step limits. start: walking frame (x, y, z [m], yaw [rad]) at t = 0.

    Raises:
        ValueError: bad inputs, or no collision-free plan within the limits.
    """
    period = timing.step_period
    n_cmd = int(np.ceil(command.duration / period))
    targets = np.array([_world(start, p) for p in command.poses(period * np.arange(1, n_cmd + 1))])
    if n_cmd == 0:
        raise ValueError(f"the velocity command lasts {command.duration} s, less than one step")
    # idle keyframes at the start: stand instead of stepping in place
    moving = [k for k in range(n_cmd) if np.linalg.norm(targets[k, :2] - np.asarray(start[:2])) > _POS_TOL
              or abs(targets[k, 2] - start[3]) > _YAW_TOL]
    k0 = moving[0] if moving else n_cmd - 1
    st0 = _Stepper(start, Side.RIGHT, foot_separation, limits, sole)
    first = _first_side(st0.remaining(targets[k0]))
    st = _Stepper(start, first, foot_separation, limits, sole)
    for k in range(k0, n_cmd):
        st.step_towards(targets[k])
    st.finish(targets[-1])
    return footsteps_from_increments(st.increments, first_side=first, foot_separation=foot_separation,
                                     timing=timing, sole=sole, start=start, limits=limits.reach(foot_separation))


def plan_from_path(waypoints, *, foot_separation: float, timing: StepTiming, sole: SoleRectangle,
                   limits: StepLimits, start: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
                   ) -> FootstepPlan:
    """Footsteps through waypoints (x [m], y [m], yaw [rad]) given in the start walking frame, each reached in
    turn (module docstring); the walk ends at the last one with the feet side by side.

    Raises:
        ValueError: bad waypoints, or no collision-free plan within the limits.
    """
    w = np.asarray(waypoints, dtype=float)
    if w.ndim != 2 or w.shape[1] != 3 or len(w) == 0 or not np.all(np.isfinite(w)):
        raise ValueError(f"a path needs waypoints [x, y, yaw] (finite numbers), got shape {w.shape}")
    targets = np.array([_world(start, p) for p in w])
    first = _first_side(w[0])
    st = _Stepper(start, first, foot_separation, limits, sole)
    for target in targets[:-1]:
        while not st.arrived(target):
            if len(st.increments) > MAX_STEPS:
                raise ValueError(f"more than {MAX_STEPS} footsteps: waypoint {target.tolist()} is out of reach")
            st.step_towards(target)
    st.finish(targets[-1])
    return footsteps_from_increments(st.increments, first_side=first, foot_separation=foot_separation,
                                     timing=timing, sole=sole, start=start, limits=limits.reach(foot_separation))
