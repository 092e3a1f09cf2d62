"""Compiled kernels of the QP layer (see :mod:`wbcbench.jit`): the certified active-set guess of a QP
(`certify_equality_qp`), the closed-form posture level of a hierarchy (`selection_lsq`) and the hierarchy's bound
test and residuals in one call (`bounds_and_residuals`). One implementation each; the tests check them against
LAPACK/numpy references (tests/qp/reference_kernels.py).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from wbcbench.jit import njit

__all__ = ["ActiveSet", "QPArrays", "certify_equality_qp", "selection_lsq", "selection_lsq_into",
           "bounds_and_residuals"]


@njit
def _cholesky_lower(A, L) -> bool:
    """L = lower Cholesky factor of the symmetric A (only A's lower triangle is read); False if A is not
    positive definite. An entry left of a row's first nonzero column (A's envelope, which L keeps) is zero
    without its dot product: a block-diagonal Hessian (the joint accelerations' block, then the contact wrenches'
    diagonal or 6x6 blocks) skips the blocks' coupling. The dot products themselves start at column 0 (zeros
    included), which LLVM vectorises; starting them at the envelope measured twice slower."""
    n = A.shape[0]
    first = np.empty(n, dtype=np.intp)
    for i in range(n):
        f = i
        for j in range(i):
            if A[i, j] != 0.0:
                f = j
                break
        first[i] = f
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False
        d = np.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            if first[i] > j:
                L[i, j] = 0.0
                continue
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
        for i in range(j):
            L[i, j] = 0.0
    return True


#: A QP's arrays for the kernels: ``min 1/2 x'Hx + g'x  s.t.  A_eq x = b_eq, l <= C x <= u, lb <= x <= ub``;
#: absent ``A_eq`` / ``C`` are (0, n) arrays, absent bounds arrays of size 0.
QPArrays = namedtuple("QPArrays", ["H", "g", "A_eq", "b_eq", "C", "l", "u", "lb", "ub"])
#: A guessed active set: the rows of C at their upper / lower bound, the variables at their upper / lower bound.
ActiveSet = namedtuple("ActiveSet", ["c_up", "c_lo", "x_up", "x_lo"])


def certify_equality_qp(qp, guess, primal_tol, dual_tol):
    """The certified active-set guess of ``ActiveSetGuessSolver`` (see its module docstring for the method):
    solve ``min 1/2 x'Hx + g'x  s.t.  A_eq x = b_eq`` and the guessed rows held with equality, in the range
    space of ``H``; then the KKT test of the full problem. ``qp``: `QPArrays`, ``guess``: `ActiveSet`.

    Returns ``(ok, x, objective)``; ``ok`` False when ``H`` or the active rows' Gram matrix is not positive
    definite or the test fails.
    """
    return _certify_equality_qp(*qp, *guess, primal_tol, dual_tol)


# flat arrays: numba types a named tuple argument in Python on every call (~2-4 us, measured), flat arrays in C
@njit
def _certify_equality_qp(H, g, A_eq, b_eq, C, l, u, lb, ub, c_up, c_lo, x_up, x_lo, primal_tol, dual_tol):
    """`certify_equality_qp` on flat arrays."""
    n = H.shape[0]
    m_eq = A_eq.shape[0]
    n_up, n_lo, nx_up, nx_lo = c_up.shape[0], c_lo.shape[0], x_up.shape[0], x_lo.shape[0]
    m = m_eq + n_up + n_lo + nx_up + nx_lo
    x = np.zeros(n)
    L = np.empty((n, n))
    if not _cholesky_lower(H, L):
        return False, x, 0.0
    # W = L^-1 [E' -g]: E = [A_eq; C[c_up]; C[c_lo]; I[x_up]; I[x_lo]], e its right-hand side; its rows padded
    # with zero columns to a multiple of 4 (whole vector registers: the forward substitution's row updates have no
    # scalar remainder; 11.5 -> 10.7 us on TALOS' standing QP, the same numbers)
    mp = ((m + 1 + 3) // 4) * 4
    W = np.zeros((n, mp))
    e = np.empty(m)
    for c in range(m_eq):
        for i in range(n):
            W[i, c] = A_eq[c, i]
        e[c] = b_eq[c]
    k = m_eq
    for r in range(n_up):
        for i in range(n):
            W[i, k] = C[c_up[r], i]
        e[k] = u[c_up[r]]
        k += 1
    for r in range(n_lo):
        for i in range(n):
            W[i, k] = C[c_lo[r], i]
        e[k] = l[c_lo[r]]
        k += 1
    for r in range(nx_up):
        W[x_up[r], k] = 1.0
        e[k] = ub[x_up[r]]
        k += 1
    for r in range(nx_lo):
        W[x_lo[r], k] = 1.0
        e[k] = lb[x_lo[r]]
        k += 1
    for i in range(n):
        W[i, m] = -g[i]
    for i in range(n):  # forward substitution, all columns at once
        for kk in range(i):
            lik = L[i, kk]
            if lik != 0.0:
                for c in range(mp):
                    W[i, c] -= lik * W[kk, c]
        d = L[i, i]
        for c in range(mp):
            W[i, c] /= d
    y = np.empty(n)
    for i in range(n):
        y[i] = W[i, m]
    lam = np.zeros(m)
    if m:
        # (V'V) lam = V'u - e,  V = W[:, :m], u = W[:, m]
        S = np.zeros((m, m))
        r = np.zeros(m)
        for i in range(n):
            ui = W[i, m]
            for a in range(m):
                via = W[i, a]
                if via != 0.0:
                    r[a] += via * ui
                    for b in range(a + 1):
                        S[a, b] += via * W[i, b]
        for a in range(m):
            r[a] -= e[a]
        Ls = np.empty((m, m))
        if not _cholesky_lower(S, Ls):
            return False, x, 0.0
        for a in range(m):  # Ls z = r
            s = r[a]
            for b in range(a):
                s -= Ls[a, b] * lam[b]
            lam[a] = s / Ls[a, a]
        for a in range(m - 1, -1, -1):  # Ls' lam = z
            s = lam[a]
            for b in range(a + 1, m):
                s -= Ls[b, a] * lam[b]
            lam[a] = s / Ls[a, a]
        for i in range(n):  # y = u - V lam
            s = 0.0
            for a in range(m):
                s += W[i, a] * lam[a]
            y[i] -= s
    for i in range(n - 1, -1, -1):  # x = L^-T y
        s = y[i]
        for kk in range(i + 1, n):
            s -= L[kk, i] * x[kk]
        x[i] = s / L[i, i]
    # dual feasibility of the guessed rows
    k = m_eq
    for r_ in range(n_up):
        if not lam[k] >= -dual_tol:
            return False, x, 0.0
        k += 1
    for r_ in range(n_lo):
        if not -lam[k] >= -dual_tol:
            return False, x, 0.0
        k += 1
    for r_ in range(nx_up):
        if not lam[k] >= -dual_tol:
            return False, x, 0.0
        k += 1
    for r_ in range(nx_lo):
        if not -lam[k] >= -dual_tol:
            return False, x, 0.0
        k += 1
    # primal feasibility, equality rows and guessed rows held (NaN fails every test)
    tol = primal_tol
    for c in range(m_eq):
        s = -b_eq[c]
        for i in range(n):
            s += A_eq[c, i] * x[i]
        if not abs(s) <= tol:
            return False, x, 0.0
    m_in = C.shape[0]
    if m_in:
        cx = np.empty(m_in)
        for c in range(m_in):
            s = 0.0
            for i in range(n):
                s += C[c, i] * x[i]
            cx[c] = s
            if not (s - u[c] <= tol and l[c] - s <= tol):
                return False, x, 0.0
        for r_ in range(n_up):
            if not abs(cx[c_up[r_]] - u[c_up[r_]]) <= tol:
                return False, x, 0.0
        for r_ in range(n_lo):
            if not abs(cx[c_lo[r_]] - l[c_lo[r_]]) <= tol:
                return False, x, 0.0
    if lb.shape[0]:
        for i in range(n):
            if not (x[i] - ub[i] <= tol and lb[i] - x[i] <= tol):
                return False, x, 0.0
        for r_ in range(nx_up):
            if not abs(x[x_up[r_]] - ub[x_up[r_]]) <= tol:
                return False, x, 0.0
        for r_ in range(nx_lo):
            if not abs(x[x_lo[r_]] - lb[x_lo[r_]]) <= tol:
                return False, x, 0.0
    for i in range(n):
        if not np.isfinite(x[i]):
            return False, x, 0.0
    gx = 0.0
    for i in range(n):
        gx += g[i] * x[i]
    le = 0.0
    for a in range(m):
        le += lam[a] * e[a]
    return True, x, 0.5 * (gx - le)


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
def selection_lsq_into(P, b_P, A, c, rank_tol, x):
    """``x = argmin ||A x - c||  s.t.  P x = b_P`` when every row of ``A`` has exactly one non-zero, in distinct
    columns (a weighted posture or regularisation level: ``A = S E_J``, S diagonal, E_J selecting the variables
    J); the variables K outside J are fixed by ``P`` alone.

    With ``P = [P_K P_J]`` and the QR factorisation ``P_K = Q_K [R_K; 0]``, ``P x = b_P`` splits into
    ``R_K x_K + (Q_K' P_J)_1 x_J = (Q_K' b_P)_1`` and ``G x_J = h`` with ``G = (Q_K' P_J)_2``, ``h = (Q_K' b_P)_2``.
    In ``u = S x_J``: ``min ||u - c||  s.t.  G S^-1 u = h`` is the projection ``u = c + (G S^-1)^+ (h - G S^-1 c)``,
    computed with a Householder QR of ``(G S^-1)'`` (no normal equations); then ``x_K = R_K^-1 (Q_K' (b_P - P_J
    x_J))_1``. About 20 thousand flops for the TALOS IK (LAPACK's general ``dgglse`` does 130 thousand).

    The reflections are applied by row index (row views' reference counting cost more than the arithmetic:
    12.6 -> 10.5 us on the TALOS IK), and to the columns of ``P_J`` all at once.

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
    # Q_K' P_J, every column at once (X[t, i] = P[t, col_of[i]]): each reflection's dot products accumulate
    # along the rows of X for all columns together, i.e. vector operations over the columns instead of one short
    # dot product per column (10.1 -> 6.5 us on the TALOS IK)
    X = np.empty((r, m))
    for t in range(r):
        for i in range(m):
            X[t, i] = P[t, col_of[i]]
    acc = np.empty(m)
    for a in range(k):
        ta = tau_k[a]
        if ta == 0.0:
            continue
        for i in range(m):
            acc[i] = X[a, i]
        for t in range(a + 1, r):
            v = RK[a, t]
            for i in range(m):
                acc[i] += v * X[t, i]
        for i in range(m):
            acc[i] *= ta
            X[a, i] -= acc[i]
        for t in range(a + 1, r):
            v = RK[a, t]
            for i in range(m):
                X[t, i] -= acc[i] * v
    # G S^-1 (p, m) and h
    GS = np.empty((p, m))
    for t in range(p):
        for i in range(m):
            GS[t, i] = X[k + t, i] / scale[i]
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


@njit
def selection_lsq(P, b_P, A, c, rank_tol):
    """`selection_lsq_into` into a new array: ``(status, x)``."""
    x = np.empty(P.shape[1])
    return selection_lsq_into(P, b_P, A, c, rank_tol, x), x


@njit
def bounds_ordered(lb, ub):
    """numpy's ``(lb <= ub).all()`` in one compiled call (a quarter of its time on 50 variables): False when a bound
    is NaN or a lower bound lies above its upper one."""
    for i in range(lb.shape[0]):
        if not lb[i] <= ub[i]:
            return False
    return True


@njit
def bounds_and_residuals(A, b, x, starts, block_level, lb, ub, sums, level_sums):
    """``(max(x - ub), max(lb - x))``: the bound violations of x (NaN when x is not finite; then ``sums`` and
    ``level_sums`` are zero); into ``sums``, for each block of rows starting at ``starts[i]``, ``sum (A x - b)^2``
    over its rows (numpy's ``add.reduceat((A x - b)**2, starts)``); into ``level_sums`` those sums added up per
    level, ``block_level[i]`` being the level of block i (the outputs passed in: new arrays cost more to hand back
    than the arithmetic)."""
    n = x.shape[0]
    high = -np.inf
    low = -np.inf
    sums[:] = 0.0
    level_sums[:] = 0.0
    for i in range(n):
        xi = x[i]
        if not np.isfinite(xi):
            return np.nan, np.nan
        high = max(high, xi - ub[i])
        low = max(low, lb[i] - xi)
    m = A.shape[0]
    block = -1
    for r in range(m):
        while block + 1 < starts.shape[0] and starts[block + 1] <= r:
            block += 1
        s = -b[r]
        for i in range(n):
            s += A[r, i] * x[i]
        sums[block] += s * s
    for i in range(starts.shape[0]):
        level_sums[block_level[i]] += sums[i]
    return high, low
