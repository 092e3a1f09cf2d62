"""Rank-revealing null-space step of the hierarchical solver (LAPACK through scipy, no SVD).

For a level with stacked (weighted) equality rows ``A`` (m, n), the current point ``x`` and an orthonormal
basis ``Z`` (n, d) of the directions the levels above leave free, the projected matrix is ``M = A Z``
(m, d). A column-pivoted QR of ``M^T`` gives ``M^T P = Q R`` with ``|R_00| >= |R_11| >= ...``; the rank
``r`` counts the diagonal entries above the threshold, ``Q[:, :r]`` spans the row space of ``M`` and
``Q[:, r:]`` its null space. So ``Z Q[:, :r]`` are the directions this level uses and ``Z Q[:, r:]`` the
basis handed to the next level. The pivoted QR costs a few microseconds where an SVD of the same matrix
costs tens.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from scipy.linalg import lapack

FloatArray = npt.NDArray[np.float64]


class Projection(NamedTuple):
    """Pivoted QR of ``M^T`` (``M = A Z``, shape (m, d)) and the rotated basis ``Z Q``.

    Attributes:
        rank: numerical rank ``r`` of ``M``.
        ZQ: (n, d) ``Z Q``; its first ``r`` columns span what this level can change, the rest is the null space
            left to the levels below.
        R: (min(d, m), m) upper-trapezoidal factor (only its first ``r`` rows are used).
        perm: (m,) 0-based row permutation of ``M`` (column pivoting of ``M^T``).
    """

    rank: int
    ZQ: FloatArray
    R: FloatArray
    perm: npt.NDArray[np.intp]


def project(M: FloatArray, Z: FloatArray | None, n: int, threshold: float) -> Projection:
    """Factor ``M`` (m, d) and rotate ``Z`` (n, d; None means the identity, d = n).

    Args:
        M: (m, d) projected equality rows, m >= 1, d >= 1.
        Z: (n, d) orthonormal basis, or None for the identity.
        n: number of variables.
        threshold: diagonal entries of R with ``|R_ii| <= threshold`` count as zero (absolute, in the units of M).
    """
    d = M.shape[1]
    qr, jpvt, tau, _, info = lapack.dgeqp3(M.T)
    if info != 0:  # pragma: no cover - LAPACK argument error
        raise RuntimeError(f"dgeqp3 failed with info={info}")
    k = tau.shape[0]
    diag = np.abs(np.diagonal(qr)[:k])
    rank = int(np.count_nonzero(diag > threshold))
    if Z is None:
        if k < d:
            a = np.zeros((d, d), order="F")
            a[:, :k] = qr[:, :k]
        else:
            a = qr[:, :d]
        ZQ, _, info = lapack.dorgqr(a, tau)
    else:
        ZQ, _, info = lapack.dormqr("R", "N", qr[:, :k], tau, Z, lwork=max(1, 32 * n))
    if info != 0:  # pragma: no cover
        raise RuntimeError(f"dorgqr/dormqr failed with info={info}")
    R = np.triu(qr[:k])
    return Projection(rank, ZQ, R, jpvt - 1)


def least_squares_step(proj: Projection, r: FloatArray, damping: float) -> FloatArray:
    """Coordinates ``y`` (rank,) of the step ``z = Q[:, :rank] y`` minimising ``||M z - r||^2 + damping^2 ||z||^2``.

    With ``M[perm] = R^T Q^T``, the step only sees ``R_1 = R[:rank]``: minimise ``||R_1^T y - r[perm]||^2 +
    damping^2 ||y||^2``. Full row rank and no damping is a triangular solve; otherwise a QR of the (damped)
    (m, rank) system.

    Args:
        proj: factorisation from :func:`project`.
        r: (m,) residual ``b - A x`` of the level at the current point.
        damping: Tikhonov factor ``lambda`` >= 0, in the units of M.
    """
    rank = proj.rank
    if rank == 0:
        return np.zeros(0)
    c = r[proj.perm]
    R1 = proj.R[:rank]
    m = R1.shape[1]
    if damping == 0.0 and rank == m:
        y, info = lapack.dtrtrs(R1, c, lower=0, trans=1)
        if info == 0:
            return y
    B = R1.T
    if damping > 0.0:
        B = np.vstack([B, damping * np.eye(rank)])
        c = np.concatenate([c, np.zeros(rank)])
    qr, tau, _, _ = lapack.dgeqrf(B)
    qtc, _, _ = lapack.dormqr("L", "T", qr, tau, c[:, None], lwork=max(1, 32 * B.shape[0]))
    y, info = lapack.dtrtrs(qr[:rank], qtc[:rank, 0])
    if info != 0:  # pragma: no cover - rank guarantees a non-singular triangle
        raise RuntimeError(f"dtrtrs failed with info={info}")
    return y
