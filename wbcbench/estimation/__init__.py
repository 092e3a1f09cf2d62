"""State estimation from raw measurements: contact wrenches from ankle F/T sensors, CoP, ZMP and DCM.

Independent of the simulator: every function takes one sample or one row per control tick (pure numpy);
`BalanceEstimator` (balance.py) adds the robot model to anchor the CoM on the support foot.
"""

from ._validate import cross
from .balance import BalanceEstimator
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
    "BalanceEstimator",
    "DEFAULT_MIN_NORMAL_FORCE",
    "GRAVITY_WORLD",
    "CenterOfPressure",
    "FootMass",
    "Plane",
    "Wrench",
    "as_plane",
    "center_of_pressure",
    "contact_wrench_from_ft",
    "cross",
    "dcm",
    "ft_from_contact_wrench",
    "lipm_omega",
    "zmp_from_wrenches",
]
