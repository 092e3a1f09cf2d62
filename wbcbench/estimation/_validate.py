"""Input checks shared by the estimators: shapes, finiteness, batch sizes.

Every public estimator accepts one sample (a (3,) vector, a (3, 3) matrix) or a batch with one row per
control tick ((N, 3), (N, 3, 3)). These helpers turn inputs into float arrays and raise ValueError naming
the argument and the problem.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

_EYE3 = np.eye(3)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` along the last axis, broadcasting like np.cross; one pair of (3,) vectors by components (np.cross
    costs about 20 us per call here, ten times the arithmetic: the estimators call it every control tick)."""
    if a.shape == (3,) and b.shape == (3,):
        a0, a1, a2 = a.tolist()
        b0, b1, b2 = b.tolist()
        return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    return np.cross(a, b)


def rotate(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R v`` for one rotation (3, 3) and one vector (3,), or broadcast over batches ((N, 3, 3), (N, 3))."""
    if R.ndim == 2 and v.ndim == 1:
        return R @ v
    return np.einsum("...ij,...j->...i", R, v)


def _check_finite(name: str, a: np.ndarray) -> None:
    if not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a))[0]
        raise ValueError(f"{name} contains non-finite values (first at index {tuple(int(i) for i in bad)})")


def vec3(name: str, x: ArrayLike) -> np.ndarray:
    """`x` as a float array of shape (3,) or (N, 3), N >= 1, all finite."""
    a = np.asarray(x, dtype=float)
    if a.ndim not in (1, 2) or a.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (3,) or (N, 3), got {a.shape}")
    if a.size == 0:
        raise ValueError(f"{name} is empty (shape {a.shape})")
    _check_finite(name, a)
    return a


def rot3(name: str, x: ArrayLike, *, atol: float = 1e-6) -> np.ndarray:
    """`x` as a float array of shape (3, 3) or (N, 3, 3) of rotation matrices (checked to `atol`)."""
    a = np.asarray(x, dtype=float)
    if a.ndim not in (2, 3) or a.shape[-2:] != (3, 3):
        raise ValueError(
            f"{name} must have shape (3, 3) or (N, 3, 3), got {a.shape} "
            "(MuJoCo's site_xmat rows are flat: reshape them to (3, 3))"
        )
    if a.size == 0:
        raise ValueError(f"{name} is empty (shape {a.shape})")
    _check_finite(name, a)
    if a.ndim == 2:  # one matrix: plain products (the batch path costs ten times more on one sample)
        gram = a.T @ a
        gram -= _EYE3
        (r0, r1, r2) = a.tolist()
        det = (r0[0] * (r1[1] * r2[2] - r1[2] * r2[1]) - r0[1] * (r1[0] * r2[2] - r1[2] * r2[0])
               + r0[2] * (r1[0] * r2[1] - r1[1] * r2[0]))
        if not (np.abs(gram).max() <= atol and det > 0.0):
            raise ValueError(f"{name} is not a rotation matrix (R^T R != I or det <= 0) at sample 0")
        return a
    gram = np.einsum("...ki,...kj->...ij", a, a)
    err = np.abs(gram - np.eye(3)).reshape(-1, 9).max(axis=1)
    det = np.linalg.det(a).reshape(-1)
    bad = np.flatnonzero((err > atol) | (det <= 0.0))
    if bad.size:
        raise ValueError(
            f"{name} is not a rotation matrix (R^T R != I or det <= 0) at sample {int(bad[0])}"
        )
    return a


def batch_size(**arrays: tuple[np.ndarray, int]) -> int | None:
    """Common batch size N of arrays given as name=(array, ndim of one sample); None if none is batched.

    Raises ValueError when two batched arrays disagree on N.
    """
    n: int | None = None
    first = ""
    for name, (a, sample_ndim) in arrays.items():
        if a.ndim == sample_ndim + 1:
            if n is None:
                n, first = a.shape[0], name
            elif a.shape[0] != n:
                raise ValueError(
                    f"mismatched lengths: {first} has {n} samples but {name} has {a.shape[0]}"
                )
    return n


def positive_scalar(name: str, x: float, *, allow_zero: bool = False) -> float:
    """`x` as a finite float > 0 (or >= 0 with allow_zero)."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {x!r}") from None
    if not np.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        kind = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be finite and {kind}, got {x!r}")
    return v
