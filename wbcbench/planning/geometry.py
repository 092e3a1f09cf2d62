"""Small geometry for planning: the sole rectangle, footprints, support polygons and SO(3) helpers.

Everything here is robot-model free: it takes numbers and returns numbers. Polygons are (k, 2) arrays of
x-y vertices [m] in counter-clockwise order, in the world frame unless the name says otherwise.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from ..errors import PlanningError

__all__ = [
    "SoleRectangle",
    "convex_hull",
    "polygon_margin",
    "polygons_penetration",
    "rotation_from_yaw",
    "yaw_of",
    "so3_exp",
    "so3_log",
    "support_polygon",
]


@dataclass(frozen=True)
class SoleRectangle:
    """The contact rectangle of a foot, in the sole frame (x forward, y left, z the contact normal).

    Attributes:
        length: extent along the sole x axis [m] (TALOS: 0.20).
        width: extent along the sole y axis [m] (TALOS: 0.13).
        center_x, center_y: rectangle centre in the sole frame [m] (TALOS: 0, 0).
    """

    length: float
    width: float
    center_x: float = 0.0
    center_y: float = 0.0

    def __post_init__(self) -> None:
        for name in ("length", "width"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0.0:
                raise PlanningError(f"SoleRectangle.{name} must be a positive length in metres, got {value!r}")
        for name in ("center_x", "center_y"):
            if not np.isfinite(getattr(self, name)):
                raise PlanningError(f"SoleRectangle.{name} must be finite, got {getattr(self, name)!r}")

    @property
    def p_sole_center(self) -> np.ndarray:
        """Rectangle centre in the sole frame, shape (3,) [m]."""
        return np.array([self.center_x, self.center_y, 0.0])

    def corners_in_sole(self) -> np.ndarray:
        """The four corners in the sole frame, shape (4, 3) [m], counter-clockwise seen from +z."""
        hx, hy = 0.5 * self.length, 0.5 * self.width
        local = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
        local += (self.center_x, self.center_y)
        return np.column_stack([local, np.zeros(4)])

    def center_in_world(self, p_world_sole: np.ndarray, R_world_sole: np.ndarray) -> np.ndarray:
        """Rectangle centre in the world frame, shape (3,) [m]."""
        return np.asarray(p_world_sole, float) + np.asarray(R_world_sole, float) @ self.p_sole_center

    def footprint(self, p_world_sole: np.ndarray, R_world_sole: np.ndarray) -> np.ndarray:
        """The rectangle projected on the world x-y plane, shape (4, 2) [m], counter-clockwise.

        The projection keeps the orientation as long as the sole normal points up (R[2, 2] > 0).
        """
        corners = np.asarray(p_world_sole, float) + self.corners_in_sole() @ np.asarray(R_world_sole, float).T
        return corners[:, :2].copy()


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points (Andrew's monotone chain).

    Args:
        points: shape (n, 2) [m], n >= 1.

    Returns:
        Hull vertices, shape (k, 2), counter-clockwise, without collinear points.
    """
    pts = np.unique(np.asarray(points, float).reshape(-1, 2), axis=0)
    if len(pts) <= 2:
        return pts

    def cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
        return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))

    lower: list[np.ndarray] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-15:
            lower.pop()
        lower.append(p)
    upper: list[np.ndarray] = []
    for p in pts[::-1]:
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-15:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def polygon_margin(point: np.ndarray, polygon: np.ndarray) -> float:
    """Signed margin of a point in a convex polygon [m].

    Positive inside: the distance to the nearest edge line; negative outside (then its magnitude is a lower
    bound of the distance to the polygon).

    Args:
        point: shape (2,) or more (only x, y are used) [m].
        polygon: shape (k, 2), counter-clockwise, k >= 3.
    """
    poly = np.asarray(polygon, float)
    p = np.asarray(point, float)[:2]
    edges = np.roll(poly, -1, axis=0) - poly
    lengths = np.linalg.norm(edges, axis=1)
    inward = np.column_stack([-edges[:, 1], edges[:, 0]]) / lengths[:, None]
    return float(np.min(np.sum((p - poly) * inward, axis=1)))


def polygons_penetration(a: np.ndarray, b: np.ndarray) -> float:
    """Penetration depth of two convex polygons by the separating-axis test [m].

    Returns the smallest overlap of their projections over all edge normals: > 0 when they intersect,
    <= 0 when they are separated (or only touch).

    Args:
        a, b: shapes (k, 2) and (l, 2), convex, any winding.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    depth = np.inf
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        for ex, ey in edges:
            n = np.array([-ey, ex])
            norm = np.hypot(*n)
            if norm < 1e-15:
                continue
            n /= norm
            pa, pb = a @ n, b @ n
            overlap = min(pa.max(), pb.max()) - max(pa.min(), pb.min())
            depth = min(depth, overlap)
    return float(depth)


def rotation_from_yaw(yaw: float) -> np.ndarray:
    """Rotation about the world z axis, shape (3, 3)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def yaw_of(R: np.ndarray) -> float:
    """Heading of a rotation: the angle of its x axis projected on the world x-y plane [rad]."""
    R = np.asarray(R, float)
    return float(np.arctan2(R[1, 0], R[0, 0]))


def _hat(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def so3_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector w (axis * angle [rad]), shape (3,) -> (3, 3)."""
    w = np.asarray(w, float)
    theta = float(np.linalg.norm(w))
    K = _hat(w)
    if theta < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + np.sin(theta) / theta * K + (1.0 - np.cos(theta)) / theta**2 * K @ K


def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector (axis * angle, angle in [0, pi]) of a rotation matrix, shape (3, 3) -> (3,)."""
    R = np.asarray(R, float)
    cos_theta = np.clip(0.5 * (np.trace(R) - 1.0), -1.0, 1.0)
    theta = float(np.arccos(cos_theta))
    vee = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if theta < 1e-8:
        return 0.5 * vee
    if np.pi - theta < 1e-6:
        # Near pi: the axis from the symmetric part, sign from the skew part.
        B = 0.5 * (R + np.eye(3))
        i = int(np.argmax(np.diag(B)))
        axis = B[:, i] / np.sqrt(max(B[i, i], 1e-300))
        if axis @ vee < 0.0:
            axis = -axis
        return theta * axis / np.linalg.norm(axis)
    return theta / (2.0 * np.sin(theta)) * vee


def support_polygon(footprints: Iterable[np.ndarray]) -> np.ndarray:
    """Convex hull of one or more footprints, shape (k, 2) [m], counter-clockwise."""
    return convex_hull(np.vstack([np.asarray(f, float) for f in footprints]))

