"""Gait stages from contact flags, and the passivity gait measure (paper 000, Section 4.2, Eq. 11-12,
after Mummolo and Kim 2012).

    PGM = 1 - RMS(tau_sa) / RMS(tau_tot)                                   (11)
    RMS(tau_tot) = sqrt( int_0^T [ sum_i tau_i(t)^2 ] dt / T )             (12)

tau_sa is the torque of the stance ankle, tau_tot that of all robot joints; Table 7 reports it on three
gait stages. Choices (the paper names the stages but not the ankle per stage):
- double support: tau_sa = both ankles (both feet are stance feet);
- single support: tau_sa = the ankle of the foot in contact ("single S. corresponding to the stance ankle");
- flying foot: the same ticks as single support, tau_sa = the ankle of the foot in the air ("flying F.
  where the foot has no contact with the ground").
An ankle is all its actuated joints (TALOS: leg_*_5 pitch and leg_*_6 roll). Each stage pools all of its
ticks over the run (T = total time spent in that stage), so a stage's PGM is one ratio of two integrals,
not a mean of per-step ratios. tau_tot includes the ankles. Ticks without any contact are in no stage.
A stage absent from the run, or with zero total torque, gives NaN.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import Enum
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ._validate import booleans, durations, same_length, series


class GaitStage(str, Enum):
    """Contact state of a tick."""

    DOUBLE_SUPPORT = "double_support"
    LEFT_SUPPORT = "left_support"
    """Single support on the left foot (right foot in the air)."""
    RIGHT_SUPPORT = "right_support"
    """Single support on the right foot (left foot in the air)."""
    NO_CONTACT = "no_contact"


class GaitSegment(NamedTuple):
    """A maximal run of ticks with the same gait stage.

    Attributes:
        stage: the gait stage.
        start: first tick index (inclusive).
        stop: last tick index + 1 (exclusive), so ticks are `range(start, stop)`.
    """

    stage: GaitStage
    start: int
    stop: int

    @property
    def n_ticks(self) -> int:
        return self.stop - self.start


class PassivityGaitMeasure(NamedTuple):
    """PGM per gait stage (dimensionless, <= 1; 1 = passive ankle, 0 = only the ankle works); NaN if the
    stage does not occur or has no torque."""

    double_support: float
    single_support: float
    flying_foot: float


def _contacts(left_contact: ArrayLike, right_contact: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    left = booleans("left_contact", left_contact)
    right = booleans("right_contact", right_contact)
    same_length(left_contact=left, right_contact=right)
    return left, right


def _stage_codes(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    # 0 double, 1 left support, 2 right support, 3 no contact
    return np.where(left & right, 0, np.where(left, 1, np.where(right, 2, 3)))


_STAGE_OF_CODE = (
    GaitStage.DOUBLE_SUPPORT,
    GaitStage.LEFT_SUPPORT,
    GaitStage.RIGHT_SUPPORT,
    GaitStage.NO_CONTACT,
)


def split_gait_stages(left_contact: ArrayLike, right_contact: ArrayLike) -> list[GaitSegment]:
    """Split per-tick contact flags into maximal segments of constant gait stage.

    Args:
        left_contact: (N,) booleans, left foot in contact at each tick (planned or sensed; debounce sensed
            contacts first if they chatter at touch-down).
        right_contact: (N,) booleans, right foot in contact.

    Returns:
        Segments in time order covering ticks 0..N-1 exactly once.
    """
    left, right = _contacts(left_contact, right_contact)
    codes = _stage_codes(left, right)
    starts = np.concatenate(([0], np.flatnonzero(np.diff(codes)) + 1))
    stops = np.concatenate((starts[1:], [codes.shape[0]]))
    return [GaitSegment(_STAGE_OF_CODE[codes[a]], int(a), int(b)) for a, b in zip(starts, stops, strict=True)]


def torque_rms(tau: ArrayLike, dt: float | ArrayLike | None = None) -> float:
    """RMS of Eq. 12: sqrt( sum_k dt_k sum_i tau_ki^2 / sum_k dt_k ) [N m].

    Args:
        tau: (N,) or (N, n_joints) torques [N m], one row per tick.
        dt: scalar or (N,) tick durations [s]; None for uniform ticks (the result does not depend on a
            constant dt).
    """
    t = series("tau", tau)
    if t.ndim == 1:
        t = t[:, None]
    h = np.ones(t.shape[0]) if dt is None else durations(dt, t.shape[0])
    return float(np.sqrt(h @ (t**2).sum(axis=1) / h.sum()))


def _joint_columns(name: str, cols: Sequence[int], n_joints: int) -> np.ndarray:
    idx = np.asarray(cols)
    if idx.ndim != 1 or idx.size == 0 or not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"{name} must be a non-empty sequence of joint column indices (ints), got {cols!r}")
    if np.any(idx < 0) or np.any(idx >= n_joints):
        raise ValueError(f"{name} indices must lie in [0, {n_joints}) (columns of tau), got {idx.tolist()}")
    if np.unique(idx).size != idx.size:
        raise ValueError(f"{name} has repeated indices: {idx.tolist()}")
    return idx


def _ratio(num: float, den: float) -> float:
    return float("nan") if den <= 0.0 else 1.0 - float(np.sqrt(num / den))


def passivity_gait_measure(
    tau: ArrayLike,
    left_contact: ArrayLike,
    right_contact: ArrayLike,
    *,
    left_ankle: Sequence[int],
    right_ankle: Sequence[int],
    dt: float | ArrayLike | None = None,
) -> PassivityGaitMeasure:
    """PGM (Eq. 11-12) on the double-support, single-support and flying-foot stages.

    Args:
        tau: (N, n_joints) actuated joint torques [N m], one row per tick.
        left_contact: (N,) booleans, left foot in contact.
        right_contact: (N,) booleans, right foot in contact.
        left_ankle: columns of `tau` that are the left ankle joints (TALOS: leg_left_5, leg_left_6).
        right_ankle: columns of `tau` that are the right ankle joints.
        dt: scalar or (N,) tick durations [s]; None for uniform ticks.

    Returns:
        PassivityGaitMeasure(double_support, single_support, flying_foot), each
        1 - sqrt(int sum_{i in ankle(s)} tau_i^2 dt / int sum_i tau_i^2 dt) over that stage's ticks.
    """
    t = series("tau", tau)
    if t.ndim != 2:
        raise ValueError(f"tau must have shape (N, n_joints), got {t.shape}")
    left, right = _contacts(left_contact, right_contact)
    same_length(tau=t, left_contact=left)
    la = _joint_columns("left_ankle", left_ankle, t.shape[1])
    ra = _joint_columns("right_ankle", right_ankle, t.shape[1])
    if np.intersect1d(la, ra).size:
        raise ValueError(f"left_ankle {la.tolist()} and right_ankle {ra.tolist()} share columns")
    h = np.ones(t.shape[0]) if dt is None else durations(dt, t.shape[0])

    sq = t**2
    total = h * sq.sum(axis=1)  # per-tick dt * sum_i tau_i^2
    left_sq = h * sq[:, la].sum(axis=1)
    right_sq = h * sq[:, ra].sum(axis=1)
    codes = _stage_codes(left, right)
    ds, ls, rs = codes == 0, codes == 1, codes == 2
    ss = ls | rs

    double = _ratio(left_sq[ds].sum() + right_sq[ds].sum(), total[ds].sum()) if ds.any() else float("nan")
    single = _ratio(left_sq[ls].sum() + right_sq[rs].sum(), total[ss].sum()) if ss.any() else float("nan")
    flying = _ratio(right_sq[ls].sum() + left_sq[rs].sum(), total[ss].sum()) if ss.any() else float("nan")
    return PassivityGaitMeasure(double, single, flying)
