"""Vectorised quaternion helpers. Quaternions are (x, y, z, w), scalar last (pinocchio's and scipy's order)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from scipy.spatial.transform import Rotation

FloatArray = npt.NDArray[np.float64]


def normalize(q: FloatArray) -> FloatArray:
    """Unit quaternions, same shape (..., 4)."""
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def to_matrix(q: FloatArray) -> FloatArray:
    """(..., 4) quaternions (normalised here) -> (..., 3, 3) rotation matrices."""
    q = np.asarray(q, dtype=float)
    if q.shape == (4,):  # fast path for one quaternion
        return pin.Quaternion(float(q[3]), float(q[0]), float(q[1]), float(q[2])).normalized().matrix()
    q = normalize(q)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    return np.moveaxis(np.array(rows, dtype=float), (0, 1), (-2, -1))


def from_matrix(R: FloatArray) -> FloatArray:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions with w >= 0."""
    R = np.asarray(R, dtype=float)
    q = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat().reshape(*R.shape[:-2], 4)
    return np.where(q[..., 3:4] < 0.0, -q, q)


def slerp(q0: FloatArray, q1: FloatArray, alpha: float | FloatArray) -> FloatArray:
    """Spherical interpolation between unit quaternions (..., 4), shortest path; ``alpha`` in [0, 1]."""
    q0 = np.asarray(q0, dtype=float)
    q1 = np.asarray(q1, dtype=float)
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0.0, -q1, q1)
    dot = np.abs(dot)
    alpha = np.asarray(alpha, dtype=float)
    if alpha.ndim:
        alpha = alpha[..., None]
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    small = sin_theta < 1e-9
    safe = np.where(small, 1.0, sin_theta)
    w0 = np.where(small, 1.0 - alpha, np.sin((1.0 - alpha) * theta) / safe)
    w1 = np.where(small, alpha, np.sin(alpha * theta) / safe)
    return normalize(w0 * q0 + w1 * q1)


def axis_rotations(axis: str, angles: FloatArray) -> FloatArray:
    """Rotation matrices (N, 3, 3) about ``axis`` ("x", "y" or "z") by ``angles`` (N,) [rad]."""
    c, s = np.cos(angles), np.sin(angles)
    one, zero = np.ones_like(angles), np.zeros_like(angles)
    if axis == "x":
        rows = [[one, zero, zero], [zero, c, -s], [zero, s, c]]
    elif axis == "y":
        rows = [[c, zero, s], [zero, one, zero], [-s, zero, c]]
    elif axis == "z":
        rows = [[c, -s, zero], [s, c, zero], [zero, zero, one]]
    else:  # pragma: no cover - callers validate
        raise ValueError(f"unknown axis {axis!r}")
    return np.moveaxis(np.array(rows, dtype=float), (0, 1), (-2, -1))
