"""Controller compute time per control tick (paper 000, Table 8 reports mean and peaks)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ._validate import series


class TimingStats(NamedTuple):
    """Compute-time statistics over ticks, all in microseconds [us].

    Attributes:
        mean: mean time per tick.
        median: median time per tick.
        p99: 99th percentile (linear interpolation between order statistics, numpy's default).
        max: largest time (the paper's "peak").
        n_ticks: number of ticks measured.
    """

    mean: float
    median: float
    p99: float
    max: float
    n_ticks: int


def timing_stats(durations_s: ArrayLike) -> TimingStats:
    """Statistics of per-tick compute durations.

    Args:
        durations_s: (N,) wall-clock durations [s] of each tick's controller call (e.g. differences of
            `time.perf_counter()`), all finite and >= 0.

    Returns:
        TimingStats in microseconds.
    """
    d = series("durations_s", durations_s)
    if d.ndim != 1:
        raise ValueError(f"durations_s must have shape (N,), got {d.shape}")
    if np.any(d < 0.0):
        raise ValueError(f"durations_s must be >= 0 [s], first negative at tick {int(np.argmax(d < 0.0))}")
    us = d * 1e6
    return TimingStats(
        mean=float(us.mean()),
        median=float(np.median(us)),
        p99=float(np.percentile(us, 99.0)),
        max=float(us.max()),
        n_ticks=int(us.shape[0]),
    )
