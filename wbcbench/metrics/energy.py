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

Electrical energy (not in the paper; the robot's realism preset gives the motors, `wbcbench.sim.realism.Motors`):

    i_i = tau_i / (N_i k_t,i),   P_cu,i = c R_i i_i^2,   P_el,i = tau_i omega_i + P_cu,i,
    E_el = int_0^T sum_i max(P_el,i, 0) dt   (no regeneration)   or   int_0^T sum_i P_el,i dt   (regeneration),
    C_el = E_el / (m g D)

with tau_i the joint torque the actuator delivers and omega_i the actuator-side joint velocity (the logged `tau`
and `v`: with a realism preset's drive elasticity, the motor side), N_i the gear ratio, k_t,i the motor torque
constant and R_i the winding resistance. c = 3/2 in the `dq` convention (three-phase motor: R per phase, i the
q-axis current amplitude of the amplitude-invariant Park transform, so the three phase currents of amplitude i
dissipate 3 x R i^2 / 2), c = 1 in the `dc` convention (an equivalent DC motor). Not modelled: gear efficiency
(the mechanical power at the joint is the motor's), iron and drive-electronics losses, and the motor's own
friction beyond what the simulation has (a realism preset's joint friction is inside tau: the actuator torque
overcomes it, so its losses are in tau omega). Without regeneration, a drive that brakes (P_el,i < 0)
dissipates that power and draws nothing; with it, the negative power returns to the supply and offsets the
other joints' draw (an ideal common bus).
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


class ElectricalEnergy(NamedTuple):
    """Electrical energy of the actuators over a run (see the module docstring).

    Attributes:
        e_el: E_el, the electrical energy drawn [J].
        e_cu: the copper losses int sum_i P_cu,i dt [J].
        work: the net mechanical work int sum_i tau_i omega_i dt [J].
    """

    e_el: float
    e_cu: float
    work: float


COPPER_LOSS_FACTOR = {"dq": 1.5, "dc": 1.0}
"""c in P_cu = c R i^2 per current convention (module docstring)."""


def _per_joint(name: str, values: ArrayLike, n: int, *, positive: bool) -> np.ndarray:
    a = np.asarray(values, dtype=float).reshape(-1)
    if a.size != n:
        raise ValueError(f"{name} has {a.size} values for {n} joints")
    if not np.all(np.isfinite(a)) or (np.any(a <= 0) if positive else np.any(a < 0)):
        raise ValueError(f"{name} must be finite and {'> 0' if positive else '>= 0'}, got {a.tolist()}")
    return a


def motor_current(tau: ArrayLike, torque_constant: ArrayLike, gear_ratio: ArrayLike) -> np.ndarray:
    """Motor current i = tau / (N k_t) [A] per tick and joint: (N_ticks, n_joints)."""
    t = series("tau", tau)
    t = t[:, None] if t.ndim == 1 else t
    k = _per_joint("torque_constant", torque_constant, t.shape[1], positive=True)
    n = _per_joint("gear_ratio", gear_ratio, t.shape[1], positive=True)
    return t / (n * k)


def electrical_energy(tau: ArrayLike, omega: ArrayLike, dt: float | ArrayLike, *, torque_constant: ArrayLike,
                      gear_ratio: ArrayLike, resistance: ArrayLike, convention: str = "dq",
                      regeneration: bool = False) -> ElectricalEnergy:
    """E_el, the copper losses and the net mechanical work by a rectangle sum over ticks (module docstring).

    Args:
        tau, omega: (N,) or (N, n_joints) joint torques [N m] and actuator-side joint velocities [rad/s].
        dt: control period [s] (scalar) or (N,) per-tick durations.
        torque_constant: (n_joints,) k_t [N m/A], > 0.
        gear_ratio: (n_joints,) N, > 0.
        resistance: (n_joints,) R [ohm], >= 0 (per phase in the `dq` convention).
        convention: `dq` (copper loss 3/2 R i^2) or `dc` (R i^2).
        regeneration: negative electrical power returned to the supply (True) or dissipated (False).
    """
    if convention not in COPPER_LOSS_FACTOR:
        raise ValueError(f"convention must be one of {', '.join(COPPER_LOSS_FACTOR)}, got {convention!r}")
    q = joint_power(tau, omega)
    i = motor_current(tau, torque_constant, gear_ratio)
    r = _per_joint("resistance", resistance, q.shape[1], positive=False)
    p_cu = COPPER_LOSS_FACTOR[convention] * r * i * i
    p_el = q + p_cu
    h = durations(dt, q.shape[0])
    drawn = p_el.sum(axis=1) if regeneration else np.clip(p_el, 0.0, None).sum(axis=1)
    return ElectricalEnergy(float(h @ drawn), float(h @ p_cu.sum(axis=1)), float(h @ q.sum(axis=1)))


def electrical_cost_of_transport(energy: ElectricalEnergy, mass: float, distance: float, *,
                                 gravity: float = STANDARD_GRAVITY) -> float:
    """C_el = E_el / (m g D) (dimensionless, J / (N m)); ValueError for a non-positive mass, distance or gravity."""
    return energy.e_el / (positive_scalar("mass", mass) * positive_scalar("distance", distance)
                          * positive_scalar("gravity", gravity))
