"""Mechanical energy and cost of transport (paper 000, Section 4.1, Eq. 10, after Torricelli et al. 2015).

    C_et = E_m / (m g D),   C_mt = E_m+ / (m g D),   E_m = int_0^T sum_i |tau_i(t) omega_i(t)| dt,
    E_m+ = int_0^T sum_i q_i(t) dt, if q_i(t) > 0,   q_i(t) = tau_i(t) omega_i(t)

Choices:
- E_m+ takes the positive part PER JOINT, E_m+ = int sum_i max(q_i, 0) dt, as Eq. 10 writes the condition on
  q_i, not on sum_i q_i: negative work in one joint does not cancel positive work in another.
- The integral is a rectangle sum over ticks, E = sum_k P_k dt_k: exact for the zero-order-hold torque of
  a digital controller at constant power, and T = sum_k dt_k.
- The joints are the actuated joints (no free-flyer): pass the columns to include.
- D is the horizontal start-to-end displacement of the base (`horizontal_distance`), not the path length.
  The published Table 6 is consistent with that: its C values equal E / (m g D) with m g = 981 N
  (m = 100 kg, the real TALOS, not the 90.27 kg URDF) and D = 1.2 m (20 cm walk), 3.6 m (60 cm walk),
  1.8 m (stairs: 6 x 0.30 m, the 0.6 m rise NOT included) and about 1.5 m (platforms).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..types import GRAVITY
from ._validate import durations, positive_scalar, same_length, series

STANDARD_GRAVITY = GRAVITY
"""Gravity magnitude [m/s^2] used by the paper."""


class MechanicalEnergy(NamedTuple):
    """Mechanical work of the actuators over a run.

    Attributes:
        e_m: E_m = int sum_i |tau_i omega_i| dt [J].
        e_m_plus: E_m+ = int sum_i max(tau_i omega_i, 0) dt [J].
        duration: T = sum of the tick durations [s].
    """

    e_m: float
    e_m_plus: float
    duration: float


class CostOfTransport(NamedTuple):
    """Dimensionless costs of transport [J / (N m)] (the paper prints J/kg/m).

    Attributes:
        c_et: energetic cost of transport E_m / (m g D).
        c_mt: mechanical cost of transport E_m+ / (m g D).
    """

    c_et: float
    c_mt: float


def _torques_and_velocities(tau: ArrayLike, omega: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    t = series("tau", tau)
    w = series("omega", omega)
    same_length(tau=t, omega=w)
    if t.shape != w.shape:
        raise ValueError(f"tau has shape {t.shape} but omega has shape {w.shape} (one column per joint)")
    if t.ndim == 1:
        t, w = t[:, None], w[:, None]
    return t, w


def joint_power(tau: ArrayLike, omega: ArrayLike) -> np.ndarray:
    """Per-joint mechanical power q_i = tau_i omega_i [W].

    Args:
        tau: (N,) or (N, n_joints) joint torques [N m] (forces [N] for prismatic joints), one row per tick.
        omega: same shape, joint velocities [rad/s] ([m/s]).

    Returns:
        (N, n_joints) power [W].
    """
    t, w = _torques_and_velocities(tau, omega)
    return t * w


def mechanical_energy(tau: ArrayLike, omega: ArrayLike, dt: float | ArrayLike) -> MechanicalEnergy:
    """E_m and E_m+ of Eq. 10 by a rectangle sum over ticks.

    Args:
        tau: (N,) or (N, n_joints) joint torques [N m], one row per tick.
        omega: same shape, joint velocities [rad/s].
        dt: control period [s] (scalar) or (N,) per-tick durations.

    Returns:
        MechanicalEnergy(e_m = sum_k dt_k sum_i |q_ki|, e_m_plus = sum_k dt_k sum_i max(q_ki, 0),
        duration = sum_k dt_k) [J, J, s].
    """
    q = joint_power(tau, omega)
    h = durations(dt, q.shape[0])
    e_m = float(h @ np.abs(q).sum(axis=1))
    e_m_plus = float(h @ np.clip(q, 0.0, None).sum(axis=1))
    return MechanicalEnergy(e_m, e_m_plus, float(h.sum()))


def horizontal_distance(base_positions: ArrayLike) -> float:
    """D: horizontal (x-y) distance [m] between the first and the last base position.

    Args:
        base_positions: (N, 2) or (N, 3) base (free-flyer) positions [m], world frame; z is ignored.
    """
    p = series("base_positions", base_positions)
    if p.ndim != 2 or p.shape[1] not in (2, 3):
        raise ValueError(f"base_positions must have shape (N, 2) or (N, 3), got {p.shape}")
    return float(np.linalg.norm(p[-1, :2] - p[0, :2]))


def cost_of_transport(
    energy: MechanicalEnergy,
    mass: float,
    distance: float,
    *,
    gravity: float = STANDARD_GRAVITY,
) -> CostOfTransport:
    """C_et = E_m / (m g D) and C_mt = E_m+ / (m g D) (Eq. 10).

    Args:
        energy: from `mechanical_energy` [J].
        mass: robot mass m [kg], > 0.
        distance: distance travelled D [m], > 0 (see `horizontal_distance`).
        gravity: g [m/s^2], > 0.

    Raises:
        ValueError: non-positive mass, distance or gravity (no cost of transport without travel).
    """
    if not isinstance(energy, MechanicalEnergy):
        raise ValueError(f"energy must be a MechanicalEnergy, got {type(energy).__name__}")
    m = positive_scalar("mass", mass)
    d = positive_scalar("distance", distance)
    g = positive_scalar("gravity", gravity)
    weight_distance = m * g * d
    return CostOfTransport(energy.e_m / weight_distance, energy.e_m_plus / weight_distance)
