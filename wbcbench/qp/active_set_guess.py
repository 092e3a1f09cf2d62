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
of its optimum becomes the next guess: the backend's final working set when it reports one (daqp: the rows and
bounds with a non-zero multiplier, `QPResult.working_set`), else the rows within ``active_tol`` of a bound. The
working set is the better guess: on a torque-limited tick several rows touch their bounds with dependent
gradients (a torque row and an acceleration bound of the same joint), which makes the guess's Gram matrix
singular and its certification fail; on 522 consecutive torque-limited QPs of a teleoperation replay the
next tick's certificate held 356 times from the working set against 212 from the touching rows. This is not an active-set
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

from wbcbench.qp import kernels
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
        self._empty: dict[int, tuple[FloatArray, FloatArray]] = {}
        self._flat: dict[int, tuple] = {}

    def reset(self) -> None:
        """Forget the guesses and the backend's workspace."""
        self._guesses.clear()
        self._flat.clear()
        self.backend.reset()

    # ------------------------------------------------------------------------------------------ solve
    def solve(self, problem: QPProblem) -> QPResult:
        p = problem
        entry = self._flat.get(id(p))
        if entry is None or entry[0] is not p:
            entry = self._flatten(p)
        _, key, arrays = entry
        guess = self._guesses.get(key)
        if guess is None:
            guess = self._guesses[key] = _Guess()
        ok, x, objective = kernels._certify_equality_qp(*arrays, guess.c_up, guess.c_lo, guess.x_up, guess.x_lo,
                                                        self.primal_tol, self.dual_tol)
        if ok:
            self.n_guessed += 1
            return QPResult(x, QPStatus.OPTIMAL, 0, objective, self.name, "guess")
        self.n_backend += 1
        result = self.backend.solve(p)
        if result.x is not None:
            ws = result.working_set
            self._guesses[key] = _Guess(*ws) if ws is not None else self._active_set(p, result.x)
        return result

    def _flatten(self, p: QPProblem) -> tuple:
        """(p, its structure key, the kernel's arrays of p: `kernels.QPArrays` with (0, n) / size-0 arrays for
        the absent parts), kept for the next solves of the same problem object (a controller refills one
        problem's arrays in place every tick; a `QPProblem` cannot be re-pointed at other arrays)."""
        n = p.H.shape[0]
        empty = self._empty.get(n)
        if empty is None:
            empty = self._empty[n] = (np.zeros((0, n)), np.zeros(0))
        E, z = empty
        m_eq = 0 if p.A_eq is None else p.A_eq.shape[0]
        m_in = 0 if p.C is None else p.C.shape[0]
        key = (n, m_eq, m_in, p.lb is not None)
        arrays = kernels.QPArrays(p.H, p.g, E if p.A_eq is None else p.A_eq, z if p.b_eq is None else p.b_eq,
                                  E if p.C is None else p.C, z if p.l is None else p.l, z if p.u is None else p.u,
                                  z if p.lb is None else p.lb, z if p.ub is None else p.ub)
        if len(self._flat) >= 16:  # problems made anew for each solve: keep only the recent ones
            self._flat.clear()
        entry = self._flat[id(p)] = (p, key, tuple(arrays))
        return entry

    def _certified(self, p: QPProblem, guess: _Guess, m_eq: int) -> tuple[FloatArray, float] | None:
        """The solution with ``guess`` active and its objective if it passes the KKT test, else None
        (:func:`wbcbench.qp.kernels.certify_equality_qp`)."""
        arrays = self._flatten(p)[2]
        ok, x, objective = kernels.certify_equality_qp(
            kernels.QPArrays(*arrays), kernels.ActiveSet(guess.c_up, guess.c_lo, guess.x_up, guess.x_lo),
            self.primal_tol, self.dual_tol)
        return (x, objective) if ok else None

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
