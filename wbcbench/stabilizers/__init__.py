"""Stabilizers: feedback laws that correct the planned references from measured CoM, DCM and ZMP.

`dcm`: the DCM PI controller and CoM admittance of the position-controlled schemes (paper 000 Eq. 2-4,
after Caron et al. 2019).
`balance` (imported explicitly, it needs the robot model): `BalanceStabilizer`, the estimator and DCM
stabilizer wired in front of a position-controlled whole-body controller.
"""

from .dcm import (
    IK_GAINS,
    IK_STAIRS_GAINS,
    PAPER_GAINS,
    TSID_POSITION_GAINS,
    DcmGains,
    DcmStabilizer,
    DcmStabilizerOutput,
    FirstOrderLowPass,
    com_admittance,
    dcm_from_com,
    dcm_pi_zmp,
    natural_frequency,
)

__all__ = [
    "DcmGains",
    "DcmStabilizer",
    "DcmStabilizerOutput",
    "FirstOrderLowPass",
    "IK_GAINS",
    "IK_STAIRS_GAINS",
    "TSID_POSITION_GAINS",
    "PAPER_GAINS",
    "natural_frequency",
    "dcm_from_com",
    "dcm_pi_zmp",
    "com_admittance",
]
