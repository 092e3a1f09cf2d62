"""Benchmark metrics of paper 000 (Section 4 and Tables 2-8), on plain arrays with one row per tick.

- tracking: per-axis error statistics (mean |e|, std e, peak |e|) for ZMP, CoM and feet.
- energy: E_m, E_m+ and the costs of transport C_et, C_mt (Eq. 10).
- pgm: gait stages from contact flags and the passivity gait measure (Eq. 11-12).
- timing: controller compute time per tick.
"""

from .energy import (
    STANDARD_GRAVITY,
    CostOfTransport,
    MechanicalEnergy,
    cost_of_transport,
    horizontal_distance,
    joint_power,
    mechanical_energy,
)
from .pgm import (
    GaitSegment,
    GaitStage,
    PassivityGaitMeasure,
    passivity_gait_measure,
    split_gait_stages,
    torque_rms,
)
from .timing import TimingStats, timing_stats
from .tracking import tracking_error_stats

__all__ = [
    "STANDARD_GRAVITY",
    "CostOfTransport",
    "GaitSegment",
    "GaitStage",
    "MechanicalEnergy",
    "PassivityGaitMeasure",
    "TimingStats",
    "cost_of_transport",
    "horizontal_distance",
    "joint_power",
    "mechanical_energy",
    "passivity_gait_measure",
    "split_gait_stages",
    "timing_stats",
    "torque_rms",
    "tracking_error_stats",
]
