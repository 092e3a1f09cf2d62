"""Rank-revealing null-space step of the hierarchical solver (LAPACK through scipy, no SVD).

For a level with stacked (weighted) equality rows ``A`` (m, n), the current point ``x`` and an orthonormal
basis ``Z`` (n, d) of the directions the levels above leave free, the projected matrix is ``M = A Z``
(m, d). A column-pivoted QR of ``M^T`` gives ``M^T P = Q R`` with ``|R_00| >= |R_11| >= ...``; the rank
``r`` counts the diagonal entries above the threshold, ``Q[:, :r]`` spans the row space of ``M`` and
``Q[:, r:]`` its null space. So ``Z Q[:, :r]`` are the directions this level uses and ``Z Q[:, r:]`` the
basis handed to the next level. On TALOS-sized levels the pivoted QR and the rotation of ``Z`` cost a few
microseconds each, where an SVD of the same matrix costs tens.

`selection_lsq` is the closed-form path's compiled projection (a hierarchy whose last level selects variables,
e.g. the IK's posture), see its docstring.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from scipy.linalg import lapack

from wbcbench.jit import njit

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


@njit
def _reflect_rows(R, tau, diag) -> None:
    """Householder QR of ``R'`` computed on the rows of R (k, m), k <= m: row j becomes the reflector of
    column j of ``R'`` (``diag[j]`` the diagonal of the triangular factor, the vector ``[1, R[j, j+1:]]``, the
    scalar ``tau[j]``), and rows below are transformed, so that ``R[c, a]`` (a < c) is the triangular factor's
    entry (a, c). LAPACK's dgeqr2 on the transpose, with every access along a row; each reflection written out
    on the rows by index (no row views: their reference counting cost more than the arithmetic)."""
    k, m = R.shape
    for j in range(k):
        norm2 = 0.0
        for i in range(j + 1, m):
            norm2 += R[j, i] * R[j, i]
        alpha = R[j, j]
        if norm2 == 0.0:
            tau[j] = 0.0
            diag[j] = alpha
            continue
        beta = np.sqrt(alpha * alpha + norm2)
        if alpha > 0.0:
            beta = -beta
        tau[j] = (beta - alpha) / beta
        scale = 1.0 / (alpha - beta)
        for i in range(j + 1, m):
            R[j, i] *= scale
        diag[j] = beta
        t = tau[j]
        if t == 0.0:
            continue
        for r in range(j + 1, k):
            s = R[r, j]
            for i in range(j + 1, m):
                s += R[j, i] * R[r, i]
            s *= t
            R[r, j] -= s
            for i in range(j + 1, m):
                R[r, i] -= s * R[j, i]


@njit
def _reflect_vec(V, a, t, x, j) -> None:
    """x <- (I - t w w') x, w = [0 .. 0, 1 at j, V[a, j+1:]]."""
    if t == 0.0:
        return
    m = x.shape[0]
    s = x[j]
    for i in range(j + 1, m):
        s += V[a, i] * x[i]
    s *= t
    x[j] -= s
    for i in range(j + 1, m):
        x[i] -= s * V[a, i]


@njit
def selection_lsq(P, b_P, A, c, rank_tol, x):
    """``x = argmin ||A x - c||  s.t.  P x = b_P`` when every row of ``A`` has exactly one non-zero, in distinct
    columns (a weighted posture or regularisation level: ``A = S E_J``, S diagonal, E_J selecting the variables
    J); the variables K outside J are fixed by ``P`` alone.

    With ``P = [P_K P_J]`` and the QR factorisation ``P_K = Q_K [R_K; 0]``, ``P x = b_P`` splits into
    ``R_K x_K + (Q_K' P_J)_1 x_J = (Q_K' b_P)_1`` and ``G x_J = h`` with ``G = (Q_K' P_J)_2``, ``h = (Q_K' b_P)_2``.
    In ``u = S x_J``: ``min ||u - c||  s.t.  G S^-1 u = h`` is the projection ``u = c + (G S^-1)^+ (h - G S^-1 c)``,
    computed with a Householder QR of ``(G S^-1)'`` (no normal equations); then ``x_K = R_K^-1 (Q_K' (b_P - P_J
    x_J))_1``. About 20 thousand flops for the TALOS IK (LAPACK's general ``dgglse`` does 130 thousand).

    `wbcbench.qp.kernels.selection_lsq`'s operations in the same order (the same numbers, which the tests check
    on random problems), with the reflections applied by row index instead of through row views: 12.6 -> 10.5 us
    on the TALOS IK.

    Writes x into ``x`` (n,) (a new array each call costs more to hand back than to pass in) and returns the
    status: 1 solved; 0 the structure does not apply (then the general path runs); -1 a rank test failed:
    ``|diag R_K|`` or the projection's triangular diagonal not above ``rank_tol`` times the Frobenius norm of ``P``
    (resp. of ``G S^-1``), i.e. ``P`` has no full row rank or the problem has no unique solution.
    """
    r, n = P.shape
    m = A.shape[0]
    x[:] = 0.0
    col_of = np.full(m, -1)
    scale = np.zeros(m)
    taken = np.zeros(n, dtype=np.bool_)
    for i in range(m):
        for j in range(n):
            a = A[i, j]
            if a != 0.0:
                if col_of[i] >= 0 or taken[j]:
                    return 0
                col_of[i] = j
                scale[i] = a
                taken[j] = True
        if col_of[i] < 0:
            return 0
    k = n - m
    p = r - k
    if k > r or p > m:
        return 0
    free = np.empty(k, dtype=np.int64)
    a = 0
    for j in range(n):
        if not taken[j]:
            free[a] = j
            a += 1
    fro = 0.0
    for i in range(r):
        for j in range(n):
            fro += P[i, j] * P[i, j]
    tol_P = rank_tol * max(np.sqrt(fro), 2.2250738585072014e-308)
    # QR of P_K, on the rows of its transpose
    RK = np.empty((k, r))
    for a in range(k):
        for i in range(r):
            RK[a, i] = P[i, free[a]]
    tau_k = np.zeros(max(k, 1))
    d_k = np.zeros(max(k, 1))
    _reflect_rows(RK, tau_k, d_k)
    for a in range(k):
        if not abs(d_k[a]) > tol_P:
            return -1
    # G S^-1 (p, m) and h
    col = np.empty(r)
    GS = np.empty((p, m))
    for i in range(m):
        j = col_of[i]
        for t in range(r):
            col[t] = P[t, j]
        for a in range(k):
            _reflect_vec(RK, a, tau_k[a], col, a)
        for t in range(p):
            GS[t, i] = col[k + t] / scale[i]
    bq = b_P.copy()
    for a in range(k):
        _reflect_vec(RK, a, tau_k[a], bq, a)
    rhs = np.empty(p)
    fro = 0.0
    for t in range(p):
        s = bq[k + t]
        for i in range(m):
            s -= GS[t, i] * c[i]
            fro += GS[t, i] * GS[t, i]
        rhs[t] = s
    tol_G = rank_tol * max(np.sqrt(fro), 2.2250738585072014e-308)
    # u = c + Q_G R_G^-T rhs, with (G S^-1)' = Q_G R_G
    tau_g = np.zeros(max(p, 1))
    d_g = np.zeros(max(p, 1))
    _reflect_rows(GS, tau_g, d_g)
    for t in range(p):
        if not abs(d_g[t]) > tol_G:
            return -1
    w = np.zeros(m)
    for t in range(p):  # R_G' w = rhs, R_G[b, t] = GS[t, b] for b < t
        s = rhs[t]
        for b in range(t):
            s -= GS[t, b] * w[b]
        w[t] = s / d_g[t]
    for t in range(p - 1, -1, -1):
        _reflect_vec(GS, t, tau_g[t], w, t)
    for i in range(m):
        x[col_of[i]] = (c[i] + w[i]) / scale[i]
    # x_K = R_K^-1 (Q_K' (b_P - P_J x_J))_1
    res = b_P.copy()
    for t in range(r):
        s = 0.0
        for i in range(m):
            s += P[t, col_of[i]] * x[col_of[i]]
        res[t] -= s
    for a in range(k):
        _reflect_vec(RK, a, tau_k[a], res, a)
    y = np.zeros(max(k, 1))
    for a in range(k - 1, -1, -1):  # R_K[a, e] = RK[e, a] for e > a
        s = res[a]
        for e in range(a + 1, k):
            s -= RK[e, a] * y[e]
        y[a] = s / d_k[a]
    for a in range(k):
        x[free[a]] = y[a]
    return 1
