"""Shared fixtures and finite-difference helpers for the task tests (TALOS from example-robot-data)."""

from __future__ import annotations

from collections.abc import Callable

import example_robot_data as erd
import numpy as np
import pinocchio as pin
import pytest

from wbcbench.tasks import update_kinematics, update_kinematics_velocity_level


class Talos:
    """TALOS model, half-sitting configuration, state draws and finite-difference helpers.

    Named ``erd_talos`` as a fixture so as not to shadow the project-wide ``talos`` fixture (a Robot).
    """

    def __init__(self) -> None:
        robot = erd.load("talos")
        self.model: pin.Model = robot.model
        self.q0: np.ndarray = robot.q0.copy()
        lower = self.model.lowerPositionLimit.copy()
        upper = self.model.upperPositionLimit.copy()
        # Bound the free-flyer (translation within 1 m, any orientation) whatever the URDF says.
        lower[:7] = -1.0
        upper[:7] = 1.0
        self.lower, self.upper = lower, upper

    def random_state(self, seed: int, speed: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """A configuration within the joint limits and a velocity ~ N(0, speed^2) from ``seed``."""
        pin.seed(seed)
        q = pin.randomConfiguration(self.model, self.lower, self.upper)
        v = np.random.default_rng(seed).normal(scale=speed, size=self.model.nv)
        return q, v

    def numerical_jacobian(
        self, q: np.ndarray, f: Callable[[np.ndarray], np.ndarray], h: float = 1e-6
    ) -> np.ndarray:
        """d f / d q along the tangent space (central differences with pin.integrate), (dim f, nv)."""
        columns = []
        for k in range(self.model.nv):
            dq = np.zeros(self.model.nv)
            dq[k] = h
            columns.append((f(pin.integrate(self.model, q, dq)) - f(pin.integrate(self.model, q, -dq))) / (2 * h))
        return np.stack(columns, axis=1)

    def along(
        self, q: np.ndarray, v: np.ndarray, f: Callable[[np.ndarray], np.ndarray], h: float = 1e-6
    ) -> np.ndarray:
        """d/dt f(q(t)) at t = 0 for q(t) = q (+) t v (central differences)."""
        return (f(pin.integrate(self.model, q, h * v)) - f(pin.integrate(self.model, q, -h * v))) / (2 * h)

    def at(self, data: pin.Data, q: np.ndarray, v: np.ndarray | None = None) -> pin.Data:
        """Update ``data`` at (q, v) (acceleration level when v is given, else velocity level); return it."""
        if v is None:
            update_kinematics_velocity_level(self.model, data, q)
        else:
            update_kinematics(self.model, data, q, v)
        return data


@pytest.fixture(scope="session")
def erd_talos() -> Talos:
    return Talos()
