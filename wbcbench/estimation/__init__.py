"""State estimation from raw measurements: contact wrenches from ankle F/T sensors, CoP, ZMP and DCM.

Pure numpy, independent of the simulator: every function takes one sample or one row per control tick.
"""

from .dcm import dcm, lipm_omega
from .wrench import GRAVITY_WORLD, FootMass, Wrench, contact_wrench_from_ft, ft_from_contact_wrench
from .zmp import (
    DEFAULT_MIN_NORMAL_FORCE,
    CenterOfPressure,
    Plane,
    as_plane,
    center_of_pressure,
    zmp_from_wrenches,
)

__all__ = [
    "DEFAULT_MIN_NORMAL_FORCE",
    "GRAVITY_WORLD",
    "CenterOfPressure",
    "FootMass",
    "Plane",
    "Wrench",
    "as_plane",
    "center_of_pressure",
    "contact_wrench_from_ft",
    "dcm",
    "ft_from_contact_wrench",
    "lipm_omega",
    "zmp_from_wrenches",
]
