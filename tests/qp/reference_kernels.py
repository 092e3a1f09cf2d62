"""Plain LAPACK/numpy references of the compiled QP kernels (wbcbench/qp/kernels.py), for the tests only: the
package has one implementation of each kernel; these are the same mathematics written another way."""

from __future__ import annotations

import numpy as np
from scipy.linalg import blas, lapack

from wbcbench.qp import QPProblem
from wbcbench.qp.active_set_guess import _Guess

FloatArray = np.ndarray


def certified_reference(p: QPProblem, guess: _Guess, m_eq: int, primal_tol: float = 1e-9,
                        dual_tol: float = 1e-10):
    """The reference of `wbcbench.qp.kernels.certify_equality_qp` (LAPACK/BLAS calls): the solution with the
    guessed rows active, and its objective, if it passes the KKT test; else None."""
    n = p.H.shape[0]
    L, info = lapack.dpotrf(p.H, lower=1, clean=0)
    if info != 0:
        return None
    m = m_eq + guess.size
    rhs = None
    if rhs is None:
        rhs = np.zeros((n, m + 1), order="F")
    # rhs = [E' -g], E = [A_eq; C[c_up]; C[c_lo]; I[x_up]; I[x_lo]]
    if m_eq:
        rhs[:, :m_eq] = p.A_eq.T
    if guess.size:
        e = _guess_rows(p, guess, rhs, m_eq)
        e = np.concatenate([p.b_eq, e]) if m_eq else e
    else:
        e = p.b_eq
    np.negative(p.g, out=rhs[:, m])
    # BLAS trsm, not LAPACK trtrs: OpenBLAS threads trtrs with several right-hand sides even at this size,
    # which costs 5-20x more on a loaded machine (measured)
    W = blas.dtrsm(1.0, L, rhs, lower=1, overwrite_b=1)
    u = W[:, m]  # L^-1 (-g)
    if m:
        # H x + E' lam = -g, E x = e  =>  (V'V) lam = V'u - e, x = L^-T (u - V lam), V = L^-1 E'
        V = W[:, :m]
        Ls, info = lapack.dpotrf(V.T @ V, lower=1, clean=0)
        if info != 0:  # dependent active rows
            return None
        r = V.T @ u
        r -= e
        lam, info = lapack.dpotrs(Ls, r, lower=1, overwrite_b=1)
        y = V @ lam
        np.subtract(u, y, out=y)
    else:
        lam, y = None, u.copy()
    x = blas.dtrsv(L, y, lower=1, trans=1, overwrite_x=1)  # a fresh array: the result owns it
    # dual feasibility of the guessed rows (the equality rows have free multipliers)
    if guess.size:
        k = m_eq
        for rows, sign in ((guess.c_up, 1.0), (guess.c_lo, -1.0), (guess.x_up, 1.0), (guess.x_lo, -1.0)):
            s = rows.size
            if s and not (sign * lam[k:k + s] >= -dual_tol).all():
                return None
            k += s
    # primal feasibility of every row and bound, and the equality rows and guessed rows held (complementarity):
    # the range-space solve is exact only up to the conditioning of V'V (nearly dependent active rows leave a
    # residual, measured up to 3e-6 on a torque-limited TSID tick: then the backend answers); NaN fails
    tol = primal_tol
    if m_eq:
        r = p.A_eq @ x
        r -= p.b_eq
        if not np.abs(r).max() <= tol:
            return None
    if p.C is not None:
        cx = p.C @ x
        if not ((cx - p.u).max() <= tol and (p.l - cx).max() <= tol):
            return None
        for rows, bound in ((guess.c_up, p.u), (guess.c_lo, p.l)):
            if rows.size and not np.abs(cx[rows] - bound[rows]).max() <= tol:
                return None
    if p.lb is not None:
        if not ((x - p.ub).max() <= tol and (p.lb - x).max() <= tol):
            return None
        for rows, bound in ((guess.x_up, p.ub), (guess.x_lo, p.lb)):
            if rows.size and not np.abs(x[rows] - bound[rows]).max() <= tol:
                return None
    elif not np.isfinite(x).all():
        return None
    # objective from stationarity: x'Hx = -(g'x + lam'E x) = -(g'x + lam'e)
    gx = float(p.g @ x)
    objective = 0.5 * gx if lam is None else 0.5 * (gx - float(lam @ e))
    return x, objective

def _guess_rows(p: QPProblem, guess: _Guess, rhs: FloatArray, start: int) -> FloatArray:
    """Write the guessed rows' normals into ``rhs`` columns from ``start``; return their right-hand sides."""
    k = start
    values = []
    for rows, C, bound in ((guess.c_up, p.C, p.u), (guess.c_lo, p.C, p.l)):
        if rows.size:
            rhs[:, k:k + rows.size] = C[rows].T
            values.append(bound[rows])
            k += rows.size
    for rows, bound in ((guess.x_up, p.ub), (guess.x_lo, p.lb)):
        if rows.size:
            block = rhs[:, k:k + rows.size]
            block[:] = 0.0
            block[rows, np.arange(rows.size)] = 1.0
            values.append(bound[rows])
            k += rows.size
    return np.concatenate(values)

