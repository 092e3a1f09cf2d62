"""Swing-foot trajectories: lift-off to touch-down with zero velocity and acceleration at both ends.

With tau = (t - t_start) / duration in [0, 1] and q the quintic blend 10 u^3 - 15 u^4 + 6 u^5 (q(0) = 0,
q(1) = 1, zero first and second derivatives at both ends):

- horizontal position and orientation follow q over a window [w0, w1] of tau (default the whole swing);
  the orientation moves on the SO(3) geodesic R(s) = R_start Exp(s log(R_start^T R_end)) (the yaw for flat
  feet), so its world angular velocity is s_dot R_start log(R_start^T R_end);
- height rises with one quintic from z_start to the apex z_apex = max(z_start, z_end) + apex_height at
  tau = apex_phase, then falls with another quintic to z_end. Both pieces have zero velocity and acceleration
  at their ends, so the profile is C2, peaks exactly at z_apex and supports a height change (stairs).

Before t_start the sample is the start pose, after t_start + duration the end pose, both at rest.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import PlanningError
from .footsteps import Footstep
from .geometry import so3_log

__all__ = ["quintic_blend", "quintic_from_state", "SwingSample", "SwingTrajectory", "foot_arrays", "write_swing"]


def quintic_blend(u: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The minimum-jerk blend q(u) = 10 u^3 - 15 u^4 + 6 u^5 and its first two derivatives in u.

    u is clipped to [0, 1] (q = 0 before, 1 after, derivatives 0 outside). Shapes follow u.
    """
    u = np.asarray(u, dtype=float)
    inside = (u > 0.0) & (u < 1.0)
    v = np.clip(u, 0.0, 1.0)
    q = v**3 * (10.0 - 15.0 * v + 6.0 * v * v)
    dq = np.where(inside, 30.0 * v * v * (1.0 - v) ** 2, 0.0)
    ddq = np.where(inside, 60.0 * v * (1.0 - v) * (1.0 - 2.0 * v), 0.0)
    return q, dq, ddq


def _exp_along(phi: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Exp(s_k phi) for every s_k, shape (n, 3, 3) (Rodrigues' formula, vectorised)."""
    theta = float(np.linalg.norm(phi))
    n = len(s)
    if theta < 1e-12:
        return np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    k = phi / theta
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    ang = s * theta
    return np.eye(3) + np.sin(ang)[:, None, None] * K + (1.0 - np.cos(ang))[:, None, None] * (K @ K)



def quintic_from_state(p0, v0, a0, p1, T: float, t: np.ndarray):
    """Per axis: the quintic p(t) on [0, T] from (p0, v0, a0) to (p1, 0, 0) (a re-planned swing's remaining path, a
    planned pitch brought to rest); returns p, v, a at the times t (n,), each (n, d), t clipped to [0, T]."""
    p0, v0, a0, p1 = (np.atleast_1d(np.asarray(x, float)) for x in (p0, v0, a0, p1))
    c0, c1, c2 = p0, v0, a0 / 2.0
    d = p1 - c0 - c1 * T - c2 * T**2
    dv = -c1 - 2.0 * c2 * T
    da = -2.0 * c2
    M = np.array([[T**3, T**4, T**5], [3 * T**2, 4 * T**3, 5 * T**4], [6 * T, 12 * T**2, 20 * T**3]])
    c3, c4, c5 = np.linalg.solve(M, np.vstack([d, dv, da]))
    t = np.clip(np.asarray(t, float), 0.0, T)[:, None]
    p = c0 + c1 * t + c2 * t**2 + c3 * t**3 + c4 * t**4 + c5 * t**5
    v = c1 + 2 * c2 * t + 3 * c3 * t**2 + 4 * c4 * t**3 + 5 * c5 * t**4
    a = 2 * c2 + 6 * c3 * t + 12 * c4 * t**2 + 20 * c5 * t**3
    return p, v, a


@dataclass(frozen=True, eq=False)
class SwingSample:
    """Swing foot state at one or more times (leading dimension n when sampled on an array).

    Attributes:
        p_world_sole: position [m], shape (3,) or (n, 3).
        R_world_sole: orientation, shape (3, 3) or (n, 3, 3).
        v_world_sole: linear velocity of the sole origin in the world [m/s].
        w_world_sole: angular velocity in the world frame [rad/s].
        a_world_sole: linear acceleration (time derivative of v_world_sole) [m/s^2].
        dw_world_sole: angular acceleration in the world frame [rad/s^2].
    """

    p_world_sole: np.ndarray
    R_world_sole: np.ndarray
    v_world_sole: np.ndarray
    w_world_sole: np.ndarray
    a_world_sole: np.ndarray
    dw_world_sole: np.ndarray


def foot_arrays(p_world_sole: np.ndarray, R_world_sole: np.ndarray, n: int) -> dict[str, np.ndarray]:
    """A foot's reference arrays over n ticks (`p`, `R`, `v`, `w`, `a`, `dw`, as `SwingSample`'s), at rest where
    it stands."""
    return {"p": np.tile(p_world_sole, (n, 1)), "R": np.tile(R_world_sole, (n, 1, 1)),
            "v": np.zeros((n, 3)), "w": np.zeros((n, 3)), "a": np.zeros((n, 3)), "dw": np.zeros((n, 3))}


def write_swing(arrays: dict[str, np.ndarray], sample: SwingSample, lo: int, td: int,
                p_world_sole: np.ndarray, R_world_sole: np.ndarray) -> None:
    """Into a foot's reference arrays (`foot_arrays`): the swing's sample over ticks [lo, td), and from the
    touch-down tick td on the footstep's pose, at rest (the rates left as they are: zero after a touch-down)."""
    arrays["p"][lo:td] = sample.p_world_sole
    arrays["R"][lo:td] = sample.R_world_sole
    arrays["v"][lo:td] = sample.v_world_sole
    arrays["w"][lo:td] = sample.w_world_sole
    arrays["a"][lo:td] = sample.a_world_sole
    arrays["dw"][lo:td] = sample.dw_world_sole
    arrays["p"][td:] = p_world_sole
    arrays["R"][td:] = R_world_sole


@dataclass(frozen=True, eq=False)
class SwingTrajectory:
    """A swing from one sole pose to another.

    Attributes:
        p_world_start, p_world_end: sole positions at lift-off and touch-down, shape (3,) [m].
        R_world_start, R_world_end: sole orientations, shape (3, 3).
        t_start: lift-off time [s].
        duration: swing duration [s] (> 0).
        apex_height: height of the apex above the higher end [m] (>= 0).
        apex_phase: fraction of the swing at which the apex is reached, in (0, 1).
        horizontal_window: (w0, w1), 0 <= w0 < w1 <= 1: the fraction of the swing during which the foot moves
            horizontally and turns (e.g. (0.2, 0.8) to lift before moving forward on stairs).
    """

    p_world_start: np.ndarray
    R_world_start: np.ndarray
    p_world_end: np.ndarray
    R_world_end: np.ndarray
    t_start: float
    duration: float
    apex_height: float = 0.05
    apex_phase: float = 0.5
    horizontal_window: tuple[float, float] = (0.0, 1.0)
    _log_local: np.ndarray = field(init=False, repr=False, default=None)  # log(R_start^T R_end), (3,)

    def __post_init__(self) -> None:
        for name in ("p_world_start", "p_world_end"):
            p = np.array(getattr(self, name), dtype=float)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise PlanningError(f"SwingTrajectory.{name} must be 3 finite numbers [m], got {p!r}")
            p.flags.writeable = False
            object.__setattr__(self, name, p)
        for name in ("R_world_start", "R_world_end"):
            R = np.array(getattr(self, name), dtype=float)
            if R.shape != (3, 3) or np.abs(R.T @ R - np.eye(3)).max() > 1e-6:
                raise PlanningError(f"SwingTrajectory.{name} must be a rotation matrix")
            R.flags.writeable = False
            object.__setattr__(self, name, R)
        if not np.isfinite(self.t_start):
            raise PlanningError(f"SwingTrajectory.t_start must be finite, got {self.t_start!r}")
        if not np.isfinite(self.duration) or self.duration <= 0.0:
            raise PlanningError(f"SwingTrajectory.duration must be a positive duration in seconds, got {self.duration!r}")
        if not np.isfinite(self.apex_height) or self.apex_height < 0.0:
            raise PlanningError(f"SwingTrajectory.apex_height must be >= 0 [m], got {self.apex_height!r}")
        if not 0.0 < self.apex_phase < 1.0:
            raise PlanningError(f"SwingTrajectory.apex_phase must be in (0, 1), got {self.apex_phase!r}")
        w0, w1 = (float(w) for w in self.horizontal_window)
        if not 0.0 <= w0 < w1 <= 1.0:
            raise PlanningError(f"SwingTrajectory.horizontal_window must satisfy 0 <= w0 < w1 <= 1, got "
                             f"{self.horizontal_window!r}")
        object.__setattr__(self, "horizontal_window", (w0, w1))
        log_local = so3_log(self.R_world_start.T @ self.R_world_end)
        log_local.flags.writeable = False
        object.__setattr__(self, "_log_local", log_local)

    @classmethod
    def between(cls, start: Footstep, end: Footstep, t_start: float, duration: float, *,
                apex_height: float = 0.05, apex_phase: float = 0.5,
                horizontal_window: tuple[float, float] = (0.0, 1.0)) -> "SwingTrajectory":
        """The swing from footstep `start` to footstep `end` (same foot)."""
        if start.side is not end.side:
            raise PlanningError(f"a swing goes from a foot to the same foot, got {start.side} -> {end.side}")
        return cls(start.p_world_sole, start.R_world_sole, end.p_world_sole, end.R_world_sole, t_start,
                   duration, apex_height, apex_phase, horizontal_window)

    @property
    def t_end(self) -> float:
        """Touch-down time [s]."""
        return self.t_start + self.duration

    @property
    def z_apex(self) -> float:
        """Highest sole height during the swing [m]."""
        return max(self.p_world_start[2], self.p_world_end[2]) + self.apex_height

    def sample(self, t: np.ndarray | float) -> SwingSample:
        """The swing at time(s) t [s]: scalar t gives shapes (3,), (3, 3); an array of n times gives (n, ...)."""
        scalar = np.ndim(t) == 0
        t = np.atleast_1d(np.asarray(t, dtype=float))
        T = self.duration
        tau = (t - self.t_start) / T
        # Horizontal and rotational blend over the window.
        w0, w1 = self.horizontal_window
        span = (w1 - w0) * T
        s, ds, dds = quintic_blend((tau - w0) / (w1 - w0))
        ds, dds = ds / span, dds / span**2
        p0, p1 = self.p_world_start, self.p_world_end
        p = p0 + np.outer(s, p1 - p0)
        v = np.outer(ds, p1 - p0)
        a = np.outer(dds, p1 - p0)
        # Vertical: rise to the apex, then fall.
        za, ta = self.z_apex, self.apex_phase
        q_up, dq_up, ddq_up = quintic_blend(tau / ta)
        q_dn, dq_dn, ddq_dn = quintic_blend((tau - ta) / (1.0 - ta))
        rising = tau < ta
        z0, z1 = p0[2], p1[2]
        p[:, 2] = np.where(rising, z0 + (za - z0) * q_up, za + (z1 - za) * q_dn)
        v[:, 2] = np.where(rising, (za - z0) * dq_up / (ta * T), (z1 - za) * dq_dn / ((1.0 - ta) * T))
        a[:, 2] = np.where(rising, (za - z0) * ddq_up / (ta * T) ** 2, (z1 - za) * ddq_dn / ((1.0 - ta) * T) ** 2)
        # Orientation on the geodesic.
        R = self.R_world_start @ _exp_along(self._log_local, s)
        axis_world = self.R_world_start @ self._log_local
        w = np.outer(ds, axis_world)
        dw = np.outer(dds, axis_world)
        if scalar:
            return SwingSample(p[0], R[0], v[0], w[0], a[0], dw[0])
        return SwingSample(p, R, v, w, a, dw)

    def at(self, t: float) -> SwingSample:
        """The swing at one time t [s] (shapes (3,) and (3, 3))."""
        return self.sample(float(t))
