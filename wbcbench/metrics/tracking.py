"""Tracking error statistics of a measured signal against its reference, per axis (paper 000, Tables 2-5).

The paper reports, per axis, "Average", "Standard deviation" and "Peaks" of the error (ZMP, CoM, feet).
We compute, with e = measured - reference on each axis:

    mean = mean(|e|)          (all published averages are positive and described as "an average error of
                               2 cm", i.e. a magnitude, not a signed bias that would cancel out)
    std  = std(e)             (population std, ddof = 0, of the SIGNED error. The paper does not say; the
                               published std/mean ratios of the ZMP rows are mostly 1.1-1.6, as std(e) of a
                               near-zero-mean error gives (1.25 Gaussian, 1.11 sinusoid), whereas
                               std(|e|)/mean(|e|) is 0.76 (Gaussian) or 0.48 (sinusoid))
    peak = max(|e|)
    rms  = sqrt(mean(e^2))    (not in the paper; the controller notes use it)

All values are in the unit of the inputs (metres for positions).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ._validate import booleans, check_finite, same_length, series

DEFAULT_AXES = ("x", "y", "z")


def tracking_error_stats(
    reference: ArrayLike,
    measured: ArrayLike,
    *,
    axes: Sequence[str] | None = None,
    mask: ArrayLike | None = None,
) -> dict[str, dict[str, float]]:
    """Per-axis error statistics of `measured` against `reference`.

    Args:
        reference: (N,) or (N, k) reference signal, one row per tick.
        measured: same shape as `reference`.
        axes: k axis names; default ("x", "y", "z")[:k] (k <= 3 then).
        mask: optional (N,) booleans, the ticks to include (e.g. the ticks where the ZMP is defined).
            Non-finite values are allowed on excluded ticks only.

    Returns:
        {axis: {"mean": mean |e|, "std": std e (ddof 0), "peak": max |e|, "rms": sqrt(mean e^2)}},
        e = measured - reference, in the inputs' unit.

    Raises:
        ValueError: shapes differ, empty input, mask selects no tick, non-finite values on included ticks,
            or wrong number of axis names.
    """
    ref = series("reference", reference, finite=False)
    meas = series("measured", measured, finite=False)
    n = same_length(reference=ref, measured=meas)
    if ref.shape != meas.shape:
        raise ValueError(f"reference has shape {ref.shape} but measured has shape {meas.shape}")
    if ref.ndim == 1:
        ref, meas = ref[:, None], meas[:, None]
    k = ref.shape[1]
    if axes is None:
        if k > len(DEFAULT_AXES):
            raise ValueError(f"signals have {k} columns: give `axes` names (default names cover 3)")
        names = list(DEFAULT_AXES[:k])
    else:
        names = [str(a) for a in axes]
        if len(names) != k or len(set(names)) != k:
            raise ValueError(f"axes must be {k} distinct names (one per column), got {list(axes)}")
    if mask is not None:
        keep = booleans("mask", mask)
        if keep.shape[0] != n:
            raise ValueError(f"mismatched lengths: signals have {n} ticks but mask has {keep.shape[0]}")
        if not keep.any():
            raise ValueError("mask selects no tick")
        ref, meas = ref[keep], meas[keep]
    check_finite("reference" if mask is None else "reference[mask]", ref)
    check_finite("measured" if mask is None else "measured[mask]", meas)

    e = meas - ref
    abs_e = np.abs(e)
    return {
        name: {
            "mean": float(abs_e[:, j].mean()),
            "std": float(e[:, j].std()),
            "peak": float(abs_e[:, j].max()),
            "rms": float(np.sqrt(np.mean(e[:, j] ** 2))),
        }
        for j, name in enumerate(names)
    }
