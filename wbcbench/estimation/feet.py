"""The feet as a robot senses them: sole and ankle F/T frames, and the vertical ground force on each foot."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..side import Side
from ..types import GRAVITY, Measurement

__all__ = ["FeetSensing"]



class FeetSensing:
    """Frame ids of the soles and ankle F/T sensors of `robot`, and the mass of each foot below its sensor."""

    def __init__(self, robot):
        m = robot.model
        self.sole_ids = {s: robot.sole_frame_id(s) for s in Side}
        self.sensor_ids = {s: m.getFrameId(robot.profile.feet[s].ft_sensor_frame) for s in Side}
        self.foot_mass = {s: float(robot.foot_below_sensor(s)[0]) for s in Side}

    def vertical_forces(self, meas: Measurement, data: pin.Data, R_world_frame: np.ndarray | None = None
                        ) -> dict[Side, float]:
        """Vertical ground force on each foot [N] from its ankle sensor, the foot below the sensor removed;
        `data` holds the frames' placements (`framesForwardKinematics` done), in a frame whose rotation to the
        world is `R_world_frame` (None: the world)."""
        out = {}
        for s in Side:
            R = data.oMf[self.sensor_ids[s]].rotation
            if R_world_frame is not None:
                R = R_world_frame @ R
            out[s] = float(-(R[2] @ meas.ft_force[s]) - self.foot_mass[s] * GRAVITY)
        return out
