"""Divergent component of motion (DCM) of the linear inverted pendulum (paper 000, Eq. 2).

    omega = sqrt(g / c_z),    xi = c + c_dot / omega

with c_z the CoM height above the ground (support) plane.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..types import GRAVITY
from ._validate import batch_size, positive_scalar, vec3


def lipm_omega(com_height: ArrayLike, gravity: float = GRAVITY) -> np.ndarray | float:
    """Natural frequency omega = sqrt(g / h) [1/s] of the LIPM.

    Args:
        com_height: scalar or (N,) CoM height above the ground [m], > 0.
        gravity: gravity magnitude [m/s^2], > 0.

    Returns:
        float for a scalar height, else (N,) array [1/s].
    """
    g = positive_scalar("gravity", gravity)
    h = np.asarray(com_height, dtype=float)
    if h.ndim > 1 or h.size == 0:
        raise ValueError(f"com_height must be a scalar or a non-empty (N,) array, got shape {h.shape}")
    if not np.all(np.isfinite(h)) or np.any(h <= 0.0):
        raise ValueError("com_height must be finite and > 0 [m]")
    omega = np.sqrt(g / h)
    return float(omega) if omega.ndim == 0 else omega


def dcm(com: ArrayLike, com_vel: ArrayLike, omega: ArrayLike) -> np.ndarray:
    """DCM xi = c + c_dot / omega (Eq. 2).

    Args:
        com: (3,) or (N, 3) CoM position [m], world frame.
        com_vel: (3,) or (N, 3) CoM velocity [m/s], world frame.
        omega: scalar or (N,) LIPM natural frequency [1/s], > 0 (see `lipm_omega`).

    Returns:
        (3,) or (N, 3) DCM [m], world frame.
    """
    c = vec3("com", com)
    cd = vec3("com_vel", com_vel)
    w = np.asarray(omega, dtype=float)
    if w.ndim > 1 or w.size == 0:
        raise ValueError(f"omega must be a scalar or a non-empty (N,) array, got shape {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w <= 0.0):
        raise ValueError("omega must be finite and > 0 [1/s]")
    batch_size(com=(c, 1), com_vel=(cd, 1), omega=(w, 0))
    return c + cd / (w[..., None] if w.ndim == 1 else w)
