"""Rank-revealing null-space step of the hierarchical solver (LAPACK through scipy, no SVD).

For a level with stacked (weighted) equality rows ``A`` (m, n), the current point ``x`` and an orthonormal
basis ``Z`` (n, d) of the directions the levels above leave free, the projected matrix is ``M = A Z``
(m, d). A column-pivoted QR of ``M^T`` gives ``M^T P = Q R`` with ``|R_00| >= |R_11| >= ...``; the rank
``r`` counts the diagonal entries above the threshold, ``Q[:, :r]`` spans the row space of ``M`` and
``Q[:, r:]`` its null space. So ``Z Q[:, :r]`` are the directions this level uses and ``Z Q[:, r:]`` the
basis handed to the next level. On TALOS-sized levels the pivoted QR and the rotation of ``Z`` cost a few
microseconds each, where an SVD of the same matrix costs tens.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from scipy.linalg import lapack


FloatArray = npt.NDArray[np.float64]

_UPPER_MASKS: dict[tuple[int, int], FloatArray] = {}


def _upper(block: FloatArray) -> FloatArray:
    """Upper-trapezoidal part of a (r, m) block (LAPACK leaves reflectors below the diagonal)."""
    mask = _UPPER_MASKS.get(block.shape)
    if mask is None:
        mask = _UPPER_MASKS[block.shape] = np.triu(np.ones(block.shape))
    return block * mask


class Projection(NamedTuple):
    """Pivoted QR of ``M^T`` (``M = A Z``, shape (m, d)) and the rotated basis ``Z Q``.

    Attributes:
        rank: numerical rank ``r`` of ``M``.
        ZQ: (n, d) ``Z Q``; its first ``r`` columns span what this level can change, the rest is the null space
            left to the levels below.
        qr: (d, m) LAPACK output of ``dgeqp3``: R on and above the diagonal, reflectors below.
        perm: (m,) 0-based row permutation of ``M`` (the column pivoting of ``M^T``).
    """

    rank: int
    ZQ: FloatArray
    qr: FloatArray
    perm: npt.NDArray[np.intc]


def project(M: FloatArray, Z: FloatArray | None, threshold: float) -> Projection:
    """Factor ``M`` (m, d) and rotate ``Z`` (n, d; None means the identity, d = n).

    Args:
        M: (m, d) projected equality rows, m >= 1, d >= 1.
        Z: (n, d) orthonormal basis, or None for the identity.
        threshold: diagonal entries of R with ``|R_ii| <= threshold`` count as zero (absolute, units of M).
    """
    d = M.shape[1]
    qr, jpvt, tau, _, info = lapack.dgeqp3(M.T)
    if info != 0:  # pragma: no cover - LAPACK argument error
        raise RuntimeError(f"dgeqp3 failed with info={info}")
    k = tau.shape[0]
    rank = int(np.count_nonzero(np.abs(qr.diagonal()) > threshold))
    if Z is None:
        if k < d:
            a = np.zeros((d, d), order="F")
            a[:, :k] = qr
        else:
            a = qr[:, :d]
        ZQ, _, info = lapack.dorgqr(a, tau)
    else:
        ZQ, _, info = lapack.dormqr("R", "N", qr[:, :k], tau, Z, lwork=32 * Z.shape[0])
    if info != 0:  # pragma: no cover
        raise RuntimeError(f"dorgqr/dormqr failed with info={info}")
    jpvt -= 1
    return Projection(rank, ZQ, qr, jpvt)


def least_squares_step(proj: Projection, r: FloatArray, damping: float) -> FloatArray:
    """Coordinates ``y`` (rank,) of the step ``z = Q[:, :rank] y`` minimising ``||M z - r||^2 + damping^2 ||z||^2``.

    With ``M[perm] = R^T Q^T``, the step only sees ``R_1 = R[:rank]``: minimise ``||R_1^T y - r[perm]||^2 +
    damping^2 ||y||^2``. Full row rank without damping is a triangular solve; otherwise a QR least-squares
    solve (``dgels``) of the (damped) (m, rank) system, which has full column rank.

    Args:
        proj: factorisation from :func:`project`.
        r: (m,) residual ``b - A x`` of the level at the current point.
        damping: Tikhonov factor ``lambda`` >= 0, in the units of M.
    """
    rank = proj.rank
    c = r[proj.perm]
    m = c.shape[0]
    if damping == 0.0 and rank == m:
        y, info = lapack.dtrtrs(proj.qr[:m, :m], c, lower=0, trans=1)
        if info == 0:
            return y
    B = _upper(proj.qr[:rank]).T
    if damping > 0.0:
        B = np.vstack([B, damping * np.eye(rank)])
        c = np.concatenate([c, np.zeros(rank)])
    _, y, info = lapack.dgels(B, c)
    if info != 0:  # pragma: no cover - rank guarantees full column rank
        raise RuntimeError(f"dgels failed with info={info}")
    return y[:rank]
