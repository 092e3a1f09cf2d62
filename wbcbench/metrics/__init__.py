"""Benchmark metrics of paper 000 (Section 4 and Tables 2-8), on plain arrays with one row per tick.

- tracking: per-axis error statistics (mean |e|, std e, peak |e|) for ZMP, CoM and feet.
- energy: E_m, E_m+ and the costs of transport C_et, C_mt (Eq. 10); the electrical energy E_el and C_el from a
  motor model (torque constant, gear ratio, winding resistance).
- pgm: gait stages from contact flags and the passivity gait measure (Eq. 11-12).
- timing: controller compute time per tick.
- from_log: all of the above for one run, from its log and the robot model (`compute_run_metrics`).
"""

from .energy import (
    STANDARD_GRAVITY,
    CostOfTransport,
    ElectricalEnergy,
    MechanicalEnergy,
    cost_of_transport,
    electrical_cost_of_transport,
    electrical_energy,
    horizontal_distance,
    joint_power,
    mechanical_energy,
)
from .from_log import (
    MIN_COT_DISTANCE_M,
    PAPER_MASS_KG,
    ankle_joints,
    compute_run_metrics,
    contact_zmp,
    ft_contact_wrenches,
    measured_zmp,
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
    "CostOfTransport",
    "ElectricalEnergy",
    "GaitSegment",
    "GaitStage",
    "MIN_COT_DISTANCE_M",
    "MechanicalEnergy",
    "PAPER_MASS_KG",
    "PassivityGaitMeasure",
    "STANDARD_GRAVITY",
    "TimingStats",
    "ankle_joints",
    "compute_run_metrics",
    "contact_zmp",
    "cost_of_transport",
    "electrical_cost_of_transport",
    "electrical_energy",
    "ft_contact_wrenches",
    "horizontal_distance",
    "joint_power",
    "measured_zmp",
    "mechanical_energy",
    "passivity_gait_measure",
    "split_gait_stages",
    "timing_stats",
    "torque_rms",
    "tracking_error_stats",
]
