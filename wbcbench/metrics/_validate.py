"""Input checks shared by the metrics: time series with one row per control tick."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def series(name: str, x: ArrayLike, *, finite: bool = True) -> np.ndarray:
    """`x` as a float array (N,) or (N, k) with N >= 1 and k >= 1; all finite unless `finite` is False."""
    a = np.asarray(x, dtype=float)
    if a.ndim not in (1, 2):
        raise ValueError(f"{name} must have shape (N,) or (N, k), one row per tick; got {a.shape}")
    if a.size == 0:
        raise ValueError(f"{name} is empty (shape {a.shape})")
    if finite:
        check_finite(name, a)
    return a


def check_finite(name: str, a: np.ndarray) -> None:
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise ValueError(f"{name} contains non-finite values (first at index {tuple(int(i) for i in bad)})")


def same_length(**arrays: np.ndarray) -> int:
    """Common number of rows N of the arrays; ValueError naming the two that disagree."""
    items = list(arrays.items())
    name0, a0 = items[0]
    for name, a in items[1:]:
        if a.shape[0] != a0.shape[0]:
            raise ValueError(
                f"mismatched lengths: {name0} has {a0.shape[0]} ticks but {name} has {a.shape[0]}"
            )
    return a0.shape[0]


def booleans(name: str, x: ArrayLike) -> np.ndarray:
    """`x` as a non-empty (N,) bool array; accepts bools or integers 0/1."""
    a = np.asarray(x)
    if a.ndim != 1 or a.size == 0:
        raise ValueError(f"{name} must be a non-empty (N,) array of booleans, got shape {a.shape}")
    if a.dtype == bool:
        return a
    if np.issubdtype(a.dtype, np.integer) and np.all((a == 0) | (a == 1)):
        return a.astype(bool)
    raise ValueError(f"{name} must hold booleans (or 0/1 integers), got dtype {a.dtype}")


def durations(dt: float | ArrayLike, n: int) -> np.ndarray:
    """Per-tick durations [s]: a scalar control period or an (N,) array, all finite and > 0."""
    a = np.asarray(dt, dtype=float)
    if a.ndim == 0:
        a = np.full(n, float(a))
    elif a.ndim != 1 or a.shape[0] != n:
        raise ValueError(f"dt must be a scalar or have shape ({n},) (one duration per tick), got {a.shape}")
    if not np.all(np.isfinite(a)) or np.any(a <= 0.0):
        raise ValueError("dt must be finite and > 0 [s]")
    return a


def positive_scalar(name: str, x: float) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {x!r}") from None
    if not np.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name} must be finite and > 0, got {x!r}")
    return v
