"""Ankle force/torque sensor reading -> ground contact wrench, accounting for the foot below the sensor.

Convention (MuJoCo `force` / `torque` sensors at an ankle site, as measured in SIM-NOTES.md):
the reading (f_s, m_s), expressed in the sensor (site) frame, is the wrench the leg (the parent side of
the sensor) exerts on the foot (the child subtree), the moment taken about the site origin. For a foot
of mass m whose CoM lies at p_com, static balance of the foot (its own acceleration neglected) gives the
wrench the ground exerts on the foot:

    F = -R f_s - m g
    M_site = -R m_s - (p_com - p_site) x (m g)

with R = R_world_sensor, g the gravity vector in world (default (0, 0, -9.81) m/s^2) and M_site the moment
about the sensor origin. The foot's inertial terms (m a_com, angular-momentum rate) are neglected: exact
for a foot at rest, the usual approximation for a stance foot; a swinging foot reads a small residual
wrench, which the normal-force threshold of `center_of_pressure` / `zmp_from_wrenches` removes.

Shapes: every function accepts one sample ((3,) vectors, (3, 3) matrices) or a batch with one row per
control tick ((N, 3), (N, 3, 3)); single samples broadcast against batches.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..types import GRAVITY
from ._validate import batch_size, cross, positive_scalar, rot3, rotate, vec3

GRAVITY_WORLD = np.array([0.0, 0.0, -GRAVITY])
GRAVITY_WORLD.flags.writeable = False
"""Default gravity vector in the world frame [m/s^2] (z up); read-only."""


class Wrench(NamedTuple):
    """A force and a moment in the world frame, the moment taken about `point`.

    Attributes:
        force: (3,) or (N, 3) force [N], world frame.
        moment: (3,) or (N, 3) moment about `point` [N m], world frame.
        point: (3,) or (N, 3) reduction point [m], world frame.
    """

    force: np.ndarray
    moment: np.ndarray
    point: np.ndarray

    def at(self, p_world_ref: ArrayLike) -> Wrench:
        """The same wrench with its moment taken about `p_world_ref` [m]: M_ref = M + (p - p_ref) x F."""
        ref = vec3("p_world_ref", p_world_ref)
        f, m, p = _validated_wrench(self, "wrench")
        batch_size(wrench=(f, 1), p_world_ref=(ref, 1))
        moment = m + cross(p - ref, f)
        if f.shape == ref.shape == moment.shape == (3,):
            return Wrench(f.copy(), moment, ref.copy())
        shape = np.broadcast_shapes(f.shape, ref.shape)
        return Wrench(
            np.broadcast_to(f, shape).copy(),
            np.broadcast_to(moment, shape).copy(),
            np.broadcast_to(ref, shape).copy(),
        )


@dataclass(frozen=True)
class FootMass:
    """Mass properties of the rigid body between the F/T sensor and the ground (the foot below it).

    Attributes:
        mass: mass below the sensor [kg], >= 0.
        p_sensor_com: (3,) CoM of that body in the sensor (site) frame [m].

    For TALOS (SIM-NOTES.md, sensor at the ankle joint frame): mass 1.60457 kg, CoM
    (-0.0207, -0.0002, -0.0609) m. If the sensor site is not at the ankle frame, re-express the CoM.
    """

    mass: float
    p_sensor_com: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        mass = positive_scalar("FootMass.mass", self.mass, allow_zero=True)
        com = vec3("FootMass.p_sensor_com", self.p_sensor_com)
        if com.shape != (3,):
            raise ValueError(f"FootMass.p_sensor_com must have shape (3,), got {com.shape}")
        com = com.copy()
        com.flags.writeable = False
        object.__setattr__(self, "mass", mass)
        object.__setattr__(self, "p_sensor_com", com)


def _validated_wrench(w: Wrench, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if not isinstance(w, Wrench):
        raise ValueError(f"{name} must be a Wrench(force, moment, point), got {type(w).__name__}")
    f = vec3(f"{name}.force", w.force)
    m = vec3(f"{name}.moment", w.moment)
    p = vec3(f"{name}.point", w.point)
    batch_size(**{f"{name}.force": (f, 1), f"{name}.moment": (m, 1), f"{name}.point": (p, 1)})
    return f, m, p


def _gravity(gravity: ArrayLike) -> np.ndarray:
    g = vec3("gravity", gravity)
    if g.shape != (3,):
        raise ValueError(f"gravity must have shape (3,), got {g.shape}")
    return g


def contact_wrench_from_ft(
    force_sensor: ArrayLike,
    torque_sensor: ArrayLike,
    R_world_sensor: ArrayLike,
    p_world_sensor: ArrayLike,
    foot: FootMass,
    p_world_ref: ArrayLike | None = None,
    *,
    gravity: ArrayLike = GRAVITY_WORLD,
) -> Wrench:
    """Ground contact wrench on one foot from its ankle F/T sensor reading.

    Args:
        force_sensor: (3,) or (N, 3) sensor force f_s [N] in the sensor frame: the force the leg exerts
            on the foot (MuJoCo `force` sensor convention).
        torque_sensor: (3,) or (N, 3) sensor moment m_s [N m] about the sensor origin, sensor frame.
        R_world_sensor: (3, 3) or (N, 3, 3) sensor orientation in world.
        p_world_sensor: (3,) or (N, 3) sensor origin in world [m].
        foot: mass and CoM of the body below the sensor.
        p_world_ref: (3,) or (N, 3) point [m] about which the returned moment is taken; default the sensor
            origin.
        gravity: (3,) gravity vector in world [m/s^2].

    Returns:
        The wrench the ground exerts on the foot, world frame: F = -R f_s - m g,
        M_site = -R m_s - (p_com - p_site) x m g, moved to `p_world_ref`.

    Raises:
        ValueError: on wrong shapes, non-finite values, non-rotation matrices or mismatched batch sizes.
    """
    f_s = vec3("force_sensor", force_sensor)
    m_s = vec3("torque_sensor", torque_sensor)
    R = rot3("R_world_sensor", R_world_sensor)
    p = vec3("p_world_sensor", p_world_sensor)
    if not isinstance(foot, FootMass):
        raise ValueError(f"foot must be a FootMass, got {type(foot).__name__}")
    g = _gravity(gravity)
    batch_size(force_sensor=(f_s, 1), torque_sensor=(m_s, 1), R_world_sensor=(R, 2), p_world_sensor=(p, 1))

    weight = foot.mass * g
    force = -rotate(R, f_s) - weight
    r_com = rotate(R, foot.p_sensor_com)
    moment = -rotate(R, m_s) - cross(r_com, weight)
    if force.shape == moment.shape == p.shape == (3,):
        w = Wrench(force, moment, p.copy())
    else:
        shape = np.broadcast_shapes(force.shape, moment.shape, p.shape)
        w = Wrench(
            np.broadcast_to(force, shape).copy(),
            np.broadcast_to(moment, shape).copy(),
            np.broadcast_to(p, shape).copy(),
        )
    return w if p_world_ref is None else w.at(p_world_ref)


def ft_from_contact_wrench(
    contact: Wrench,
    R_world_sensor: ArrayLike,
    p_world_sensor: ArrayLike,
    foot: FootMass,
    *,
    gravity: ArrayLike = GRAVITY_WORLD,
) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of `contact_wrench_from_ft`: the static ankle F/T reading a given contact wrench produces.

    Useful to synthesise sensor readings (tests, kinematic simulations).

    Args:
        contact: wrench the ground exerts on the foot, world frame, moment about `contact.point`.
        R_world_sensor: (3, 3) or (N, 3, 3) sensor orientation in world.
        p_world_sensor: (3,) or (N, 3) sensor origin in world [m].
        foot: mass and CoM of the body below the sensor.
        gravity: (3,) gravity vector in world [m/s^2].

    Returns:
        (force_sensor [N], torque_sensor [N m]) in the sensor frame, each (3,) or (N, 3):
        f_s = -R^T (F + m g), m_s = -R^T (M_site + (p_com - p_site) x m g).
    """
    R = rot3("R_world_sensor", R_world_sensor)
    p = vec3("p_world_sensor", p_world_sensor)
    if not isinstance(foot, FootMass):
        raise ValueError(f"foot must be a FootMass, got {type(foot).__name__}")
    g = _gravity(gravity)
    f, _, _ = _validated_wrench(contact, "contact")
    batch_size(contact=(f, 1), R_world_sensor=(R, 2), p_world_sensor=(p, 1))
    at_site = contact.at(p)
    weight = foot.mass * g
    Rt = np.swapaxes(R, -1, -2)
    f_s = -rotate(Rt, at_site.force + weight)
    r_com = rotate(R, foot.p_sensor_com)
    m_s = -rotate(Rt, at_site.moment + cross(r_com, weight))
    return f_s, m_s
