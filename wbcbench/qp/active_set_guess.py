"""A QP front end for problems solved again and again with the same active set (a controller's tick).

A whole-body controller solves one QP per tick whose optimal active set (the inequality rows and bounds
that hold with equality) rarely changes from one tick to the next; standing on two feet it is usually
empty. :class:`ActiveSetGuessSolver` first solves the equality-constrained QP with the active set of the
previous optimum, and accepts that point only if it passes the KKT test of the full problem:

* primal: every equality row, inequality row and bound holds, and every guessed row holds with equality
  (complementarity), all within ``primal_tol``;
* dual: the multiplier of every guessed row has the sign of its side (``>= -dual_tol``);
* stationarity holds by construction (x is computed from the multipliers).

For a convex QP these conditions are sufficient, so an accepted point is the optimum (unique when ``H`` is
positive definite), to the tolerances of daqp's own termination test (``primal_tol = 1e-9``,
``dual_tol = 1e-10``). Otherwise the problem goes to the backend, solved cold as always, and the active set
of its optimum (the rows within ``active_tol`` of a bound) becomes the next guess. This is not an active-set
warm start of the backend (daqp 0.11's gave wrong answers, see :class:`~wbcbench.qp.DaqpSolver`): the
backend never sees the guess, and a guess is never trusted without the test.

The equality-constrained QP ``min 1/2 x'Hx + g'x  s.t.  E x = e`` (E: the equality rows and the guessed
rows) is solved in the range space of ``H``: Cholesky ``H = L L'``, ``V = L^-1 E'``, ``u = -L^-1 g``,
multipliers from ``(V'V) lam = V'u - e``, ``x = L^-T (u - V lam)``; the factorisation a dual active-set solver
such as daqp works with. On closed-loop TALOS ticks it agrees with a cold daqp solve to 1e-13 relative; with
nearly dependent active rows (a torque-limited tick) its equality residual can reach 1e-6, which the primal
test catches (the backend answers those). It needs ``H`` positive definite: a singular ``H`` or exactly
dependent active rows make a factorisation fail, and the backend is used.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.linalg import blas, lapack

from wbcbench.qp import _jit
from wbcbench.qp.problem import QPProblem
from wbcbench.qp.result import QPResult, QPStatus
from wbcbench.qp.solver import QPSolver

__all__ = ["ActiveSetGuessSolver"]

FloatArray = npt.NDArray[np.float64]
IndexArray = npt.NDArray[np.intp]

_EMPTY = np.zeros(0, dtype=np.intp)


class _Guess:
    """Active set of the last optimum of one problem structure: rows of C at u / at l, variables at ub / lb."""

    __slots__ = ("c_up", "c_lo", "x_up", "x_lo", "size")

    def __init__(self, c_up: IndexArray = _EMPTY, c_lo: IndexArray = _EMPTY, x_up: IndexArray = _EMPTY,
                 x_lo: IndexArray = _EMPTY):
        self.c_up, self.c_lo, self.x_up, self.x_lo = c_up, c_lo, x_up, x_lo
        self.size = c_up.size + c_lo.size + x_up.size + x_lo.size


class ActiveSetGuessSolver(QPSolver):
    """Try the previous optimum's active set, certified by the KKT conditions; else the backend (see the
    module docstring).

    Args:
        backend: the solver used when the guess fails (its workspace and settings are its own).
        primal_tol: accepted violation of an inequality row or bound [constraint units].
        dual_tol: accepted multiplier of the wrong sign on a guessed row [cost units per constraint unit].
        active_tol: after a backend solve, a row or bound within ``active_tol * (1 + |bound|)`` of its bound
            is guessed active for the next solve.

    Attributes:
        jit: use the compiled kernel for the guess (default: ``wbcbench.qp._jit.JIT_ENABLED``); False runs the
            LAPACK/BLAS reference implementation, which gives the same answers.
        n_guessed: solves answered by the certified guess.
        n_backend: solves passed to the backend.
    """

    def __init__(self, backend: QPSolver, *, primal_tol: float = 1e-9, dual_tol: float = 1e-10,
                 active_tol: float = 1e-9):
        self.backend = backend
        self.name = backend.name
        self.primal_tol = float(primal_tol)
        self.dual_tol = float(dual_tol)
        self.active_tol = float(active_tol)
        self.n_guessed = 0
        self.n_backend = 0
        self._guesses: dict[tuple[int, int, int, bool], _Guess] = {}
        self._work: dict[tuple[int, int], FloatArray] = {}
        self._empty: dict[int, tuple[FloatArray, FloatArray]] = {}
        self.jit = _jit.JIT_ENABLED

    def reset(self) -> None:
        """Forget the guesses and the backend's workspace."""
        self._guesses.clear()
        self.backend.reset()

    # ------------------------------------------------------------------------------------------ solve
    def solve(self, problem: QPProblem) -> QPResult:
        p = problem
        m_eq = 0 if p.A_eq is None else p.A_eq.shape[0]
        m_in = 0 if p.C is None else p.C.shape[0]
        key = (p.H.shape[0], m_eq, m_in, p.lb is not None)
        guess = self._guesses.get(key)
        if guess is None:
            guess = self._guesses[key] = _Guess()
        certified = self._certified(p, guess, m_eq)
        if certified is not None:
            x, objective = certified
            self.n_guessed += 1
            return QPResult(x, QPStatus.OPTIMAL, 0, objective, self.name, "guess")
        self.n_backend += 1
        result = self.backend.solve(p)
        if result.x is not None:
            self._guesses[key] = self._active_set(p, result.x)
        return result

    def _certified(self, p: QPProblem, guess: _Guess, m_eq: int) -> tuple[FloatArray, float] | None:
        """The solution with ``guess`` active and its objective if it passes the KKT test, else None."""
        if self.jit:
            return self._certified_jit(p, guess)
        return self._certified_numpy(p, guess, m_eq)

    def _certified_jit(self, p: QPProblem, guess: _Guess) -> tuple[FloatArray, float] | None:
        """The compiled twin of :meth:`_certified_numpy` (:func:`wbcbench.qp._jit.certify_equality_qp`)."""
        n = p.H.shape[0]
        empty = self._empty.get(n)
        if empty is None:
            empty = self._empty[n] = (np.zeros((0, n)), np.zeros(0))
        E, z = empty
        ok, x, objective = _jit.certify_equality_qp(
            p.H, p.g, E if p.A_eq is None else p.A_eq, z if p.b_eq is None else p.b_eq,
            E if p.C is None else p.C, z if p.l is None else p.l, z if p.u is None else p.u,
            z if p.lb is None else p.lb, z if p.ub is None else p.ub,
            guess.c_up, guess.c_lo, guess.x_up, guess.x_lo, self.primal_tol, self.dual_tol)
        return (x, objective) if ok else None

    def _certified_numpy(self, p: QPProblem, guess: _Guess, m_eq: int) -> tuple[FloatArray, float] | None:
        """The reference implementation of the guess and its KKT test (LAPACK/BLAS calls)."""
        n = p.H.shape[0]
        L, info = lapack.dpotrf(p.H, lower=1, clean=0)
        if info != 0:
            return None
        m = m_eq + guess.size
        rhs = self._work.get((n, m))
        if rhs is None:
            rhs = self._work[(n, m)] = np.zeros((n, m + 1), order="F")
        # rhs = [E' -g], E = [A_eq; C[c_up]; C[c_lo]; I[x_up]; I[x_lo]]
        if m_eq:
            rhs[:, :m_eq] = p.A_eq.T
        if guess.size:
            e = self._guess_rows(p, guess, rhs, m_eq)
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
                if s and not (sign * lam[k:k + s] >= -self.dual_tol).all():
                    return None
                k += s
        # primal feasibility of every row and bound, and the equality rows and guessed rows held (complementarity):
        # the range-space solve is exact only up to the conditioning of V'V (nearly dependent active rows leave a
        # residual, measured up to 3e-6 on a torque-limited TSID tick: then the backend answers); NaN fails
        tol = self.primal_tol
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

    @staticmethod
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

    def _active_set(self, p: QPProblem, x: FloatArray) -> _Guess:
        """The rows and bounds within ``active_tol`` of their bound at ``x`` (upper side first when both)."""
        c_up = c_lo = x_up = x_lo = _EMPTY
        if p.C is not None:
            cx = p.C @ x
            up = self._at(cx, p.u)
            c_up, c_lo = np.flatnonzero(up), np.flatnonzero(self._at(cx, p.l) & ~up)
        if p.lb is not None:
            up = self._at(x, p.ub)
            x_up, x_lo = np.flatnonzero(up), np.flatnonzero(self._at(x, p.lb) & ~up)
        return _Guess(c_up, c_lo, x_up, x_lo)

    def _at(self, value: FloatArray, bound: FloatArray) -> npt.NDArray[np.bool_]:
        """Finite bounds that ``value`` reaches within ``active_tol * (1 + |bound|)``."""
        with np.errstate(invalid="ignore"):
            return np.isfinite(bound) & (np.abs(bound - value) <= self.active_tol * (1.0 + np.abs(bound)))
