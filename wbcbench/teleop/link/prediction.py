"""Operator-pose prediction: extrapolate the newest received poses over the stream's latency.

A frame that arrives has already aged by the link's delay (and ages further until the next one arrives); the
operator has moved on meanwhile. `PosePredictor` keeps the last `history` received poses of each effector, at their
sender time stamps tau_k, and extrapolates from the newest one (tau_0) to tau_0 + h, h the frame's age capped at
`max_horizon` (default 150 ms: a stalled stream is not extrapolated further, it does not fly away).

Poses are taken relative to the newest one: y_k = (p_k - p_0, log3(R_0^T R_k)) in R^6 at s_k = tau_k - tau_0 < 0,
so that the fit passes through the newest pose exactly, and the extrapolation is y(h) -> p_0 + y_p(h),
R_0 exp3(y_r(h)).

* `velocity`: constant velocity from the two newest frames, y(h) = h y_1 / s_1 (exact on a linear motion);
* `spline`: a quadratic through the newest pose, least squares over the older ones (up to `history` - 1 = 4):
  y(h) = b h + c h^2 (constant acceleration); with a single older frame, the velocity model.

History older than `max_gap` [s] before the newest frame is dropped (a stream resuming after a stall does not
extrapolate across the gap); a time stamp that goes back (a sender restart) clears it.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import pinocchio as pin

from ...errors import ConfigError

__all__ = ["DEFAULT_HORIZON", "PREDICTORS", "PosePredictor"]

#: `predict` values
PREDICTORS = ("none", "velocity", "spline")
#: default cap on the extrapolation [s]
DEFAULT_HORIZON = 0.15


class PosePredictor:
    """Extrapolation of effector poses (module docstring).

    Args:
        method: "none", "velocity" or "spline".
        max_horizon: cap on the extrapolation [s] (>= 0).
        history: frames kept (>= 2).
        max_gap: older frames farther than this before the newest are forgotten [s] (> 0).
    """

    def __init__(self, method: str = "velocity", max_horizon: float = DEFAULT_HORIZON, history: int = 5,
                 max_gap: float = 0.2):
        if method not in PREDICTORS:
            raise ConfigError(f"unknown predictor '{method}'; allowed: {', '.join(PREDICTORS)}", key="predict")
        if not (np.isfinite(max_horizon) and max_horizon >= 0):
            raise ConfigError(f"must be a duration >= 0 s, got {max_horizon!r}", key="predict_horizon")
        if history < 2 or not max_gap > 0:
            raise ConfigError("history must be >= 2 frames and max_gap > 0 s", key="predict")
        self.method = method
        self.max_horizon = float(max_horizon)
        self.max_gap = float(max_gap)
        self._frames: deque = deque(maxlen=int(history))
        self._coefficients: dict | None = None

    @property
    def newest_time(self) -> float | None:
        """Sender time stamp of the newest frame [s], None before any."""
        return self._frames[-1][0] if self._frames else None

    def push(self, tau: float, poses: dict) -> bool:
        """A newly received frame: sender time stamp tau [s], effector -> pin.SE3. Returns False (ignored) when
        tau is not newer than the newest frame unless it went back by more than `max_gap` (a restart: the
        history starts again from it)."""
        if self._frames:
            last = self._frames[-1][0]
            if tau <= last:
                if last - tau <= self.max_gap:
                    return False
                self._frames.clear()
        self._frames.append((float(tau), {k: (np.array(M.translation), np.array(M.rotation))
                                          for k, M in poses.items()}))
        while self._frames[0][0] < tau - self.max_gap:
            self._frames.popleft()
        self._coefficients = None
        return True

    def horizon(self, age: float) -> float:
        """The extrapolation used for a frame `age` seconds old: clipped to [0, max_horizon]; 0 without a
        predictor."""
        if self.method == "none" or not np.isfinite(age):
            return 0.0
        return float(min(max(age, 0.0), self.max_horizon))

    def _fit(self) -> dict:
        """Per effector (p0, R0, b, c): y(h) = b h + c h^2 about the newest pose (c = 0: constant velocity;
        b = c = 0: no older frame). Computed once per received frame."""
        tau0, newest = self._frames[-1]
        older = list(self._frames)[:-1]
        s = np.array([tau - tau0 for tau, _ in older])  # < 0
        fit = {}
        for k, (p0, R0) in newest.items():
            b = c = np.zeros(6)
            Y = np.array([np.concatenate([f[k][0] - p0, pin.log3(R0.T @ f[k][1])]) for _, f in older if k in f])
            if older and len(Y) == len(older):
                if self.method == "spline" and len(older) >= 2:
                    (b, c), *_ = np.linalg.lstsq(np.column_stack([s, s * s]), Y, rcond=None)
                else:
                    b = Y[-1] / s[-1]  # the newest older frame: constant velocity
            fit[k] = (p0, R0, b, c)
        return fit

    def predict(self, age: float) -> tuple[dict, dict, float]:
        """(effector -> pin.SE3 extrapolated over `horizon(age)`, effector -> the rate of that extrapolation (6,)
        [m/s, rad/s per second of sender time, world axes], the horizon used [s]). Without an older frame: the
        newest poses and zero rates; without a predictor (`none`): the newest poses and the velocity model's
        rates (a feed-forward estimate)."""
        if not self._frames:
            return {}, {}, 0.0
        if self._coefficients is None:
            self._coefficients = self._fit()
        h = self.horizon(age)
        poses, rates = {}, {}
        for k, (p0, R0, b, c) in self._coefficients.items():
            y, dy = b * h + c * (h * h), b + (2.0 * h) * c
            R = R0 @ pin.exp3(y[3:]) if h > 0 else R0
            poses[k] = pin.SE3(R, p0 + y[:3])
            rates[k] = np.concatenate([dy[:3], R @ dy[3:]])  # body rate of the log, to world axes (small steps)
        return poses, rates, h
