"""Fall prediction from what the robot measures: the capture point against the support polygon, and the trunk's
tilt rate.

Each tick, from the measurement only (encoders, base estimate, IMU, ankle F/T): the CoM c and its velocity
(pinocchio on the measured state), the instantaneous capture point xi = c_xy + c_dot_xy / omega with
omega = sqrt(g / (c_z - ground)), and the support polygon: the convex hull of the sole corners of the feet whose
F/T sensors read at least `load_threshold` N. A fall is predicted when xi is outside the polygon by more than
`margin` (a point where the robot cannot stop without stepping, Pratt et al. 2006), or when the base rotates faster
than `max_tilt_rate` about a horizontal axis, or when no foot is loaded.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..side import Side
from ..types import GRAVITY, Measurement
from .feet import FeetSensing

__all__ = ["FallPredictor", "convex_hull", "signed_distance_to_polygon"]



def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (k, 2) of points (n, 2) (monotone chain)."""
    pts = sorted(map(tuple, np.asarray(points, float)))
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def signed_distance_to_polygon(p: np.ndarray, hull: np.ndarray) -> float:
    """Distance [m] from p (2,) to a convex counter-clockwise polygon's boundary: > 0 inside, < 0 outside."""
    n = len(hull)
    if n < 3:
        return -math.inf
    inside = math.inf
    outside = 0.0
    for i in range(n):
        a, b = hull[i], hull[(i + 1) % n]
        e = b - a
        L = math.hypot(e[0], e[1])
        d = (e[0] * (p[1] - a[1]) - e[1] * (p[0] - a[0])) / L  # > 0 on the inner side of the edge
        inside = min(inside, d)
    if inside >= 0.0:
        return inside
    # outside: the distance to the nearest edge segment
    best = math.inf
    for i in range(n):
        a, b = hull[i], hull[(i + 1) % n]
        e = b - a
        s = min(1.0, max(0.0, float((p - a) @ e) / float(e @ e)))
        best = min(best, float(np.hypot(*(a + s * e - p))))
    outside = -best
    return outside


class FallPredictor:
    """The predicted-fall signal of the module docstring. `update(meas)` returns the tick's log values:
    (capture point x, y [m], its distance inside the support polygon [m] (< 0 outside), tilt rate [rad/s],
    predicted 0/1); `first_prediction_t` is the time of the first prediction (None if none)."""

    LOG_LABELS = ("cp_x", "cp_y", "cp_margin", "tilt_rate", "predicted")

    def __init__(self, robot, *, margin: float = 0.05, max_tilt_rate: float = 1.5, load_threshold: float = 50.0):
        self.robot = robot
        self.margin = margin
        self.max_tilt_rate = max_tilt_rate
        self.load_threshold = load_threshold
        m = robot.model
        self.model, self.data = m, m.createData()
        self.feet = FeetSensing(robot)
        self.corners = robot.profile.sole.corners
        self.first_prediction_t: float | None = None
        self.log = np.full(len(self.LOG_LABELS), np.nan)

    def update(self, meas: Measurement) -> np.ndarray:
        m, d = self.model, self.data
        pin.centerOfMass(m, d, meas.q, meas.v)
        pin.framesForwardKinematics(m, d, meas.q)
        c, cd = d.com[0], d.vcom[0]
        pts, ground = [], math.inf
        fz = self.feet.vertical_forces(meas, d)
        for s in Side:
            M = d.oMf[self.feet.sole_ids[s]]
            ground = min(ground, float(M.translation[2]))
            if fz[s] >= self.load_threshold:
                pts.append((M.rotation @ self.corners.T).T[:, :2] + M.translation[:2])
        height = max(float(c[2]) - ground, 0.1)
        omega = math.sqrt(GRAVITY / height)
        cp = c[:2] + cd[:2] / omega
        margin = signed_distance_to_polygon(cp, convex_hull(np.vstack(pts))) if pts else -math.inf
        w = meas.v[3:5]  # base angular velocity (LOCAL): roll and pitch rates
        tilt_rate = float(math.hypot(w[0], w[1]))
        predicted = (margin < -self.margin) or tilt_rate > self.max_tilt_rate
        if predicted and self.first_prediction_t is None:
            self.first_prediction_t = float(meas.t)
        log = self.log
        log[0], log[1] = cp
        log[2] = margin if math.isfinite(margin) else -1.0
        log[3] = tilt_rate
        log[4] = float(predicted)
        return log
