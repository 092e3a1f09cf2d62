"""DAQP backend (dual active-set, Arnstrom et al. 2022): the default QP solver."""

from __future__ import annotations

from typing import Any

import daqp
import numpy as np
import numpy.typing as npt

from wbcbench.errors import QPError
from wbcbench.qp.problem import QPProblem
from wbcbench.qp.result import QPResult, QPStatus
from wbcbench.qp.solver import QPSolver

__all__ = ["DaqpSolver", "DAQP_EXIT_FLAGS"]

# daqp exit flags (include/constants.h of daqp 0.11) mapped to our status.
DAQP_EXIT_FLAGS: dict[int, QPStatus] = {
    2: QPStatus.OPTIMAL,  # optimal with soft constraints relaxed; we never mark a row soft
    1: QPStatus.OPTIMAL,
    -1: QPStatus.INFEASIBLE,
    -2: QPStatus.NUMERICAL,  # cycling
    -3: QPStatus.UNBOUNDED,
    -4: QPStatus.MAX_ITER,  # iteration limit
    -5: QPStatus.NUMERICAL,  # non-convex: H not positive semi-definite
    -6: QPStatus.NUMERICAL,  # overdetermined initial working set (dependent, contradicting equalities)
    -7: QPStatus.MAX_ITER,  # time limit
    -8: QPStatus.NUMERICAL,  # problem class not supported
}
"""daqp exit flag -> :class:`QPStatus`; any other flag maps to :attr:`QPStatus.NUMERICAL`."""

_SENSE_INEQUALITY = 0
_SENSE_EQUALITY = 5  # DAQP_ACTIVE | DAQP_IMMUTABLE: a row that stays in the working set

_DEFAULTS: dict[str, float] = {"primal_tol": 1e-9, "dual_tol": 1e-10}


class DaqpSolver(QPSolver):
    """QP backend on ``daqp.Model`` (one workspace, set up once per problem structure).

    daqp solves ``min 1/2 x^T H x + f^T x`` s.t. ``blower <= A x <= bupper``, where the first
    ``len(bupper) - rows(A)`` entries of the bound vectors are simple bounds on the first variables. This
    class stacks the problem as::

        A      = [A_eq; C]                  (m_eq + m_in, n)
        bupper = [ub; b_eq; u]              (n_box + m_eq + m_in,), n_box = n with box bounds, else 0
        blower = [lb; b_eq; l]
        sense  = [0 ...; 5 ...; 0 ...]      5 marks an equality row (active and immutable)

    into buffers allocated when the structure changes and reused otherwise. Between calls of the same
    structure the daqp workspace is updated in place (no set-up, no allocation of our buffers).

    No active-set warm start: every update resets daqp's working set. With daqp 0.11, restarting from the
    previous active set after ``H`` or ``A`` changed returned NaN with exit flag 1 on about 18 % of the
    random problem sequences of ``tests/qp``, and, worse, a finite but wrong point with exit flag 1 on 13 of
    6000 solves of random sequences even with a cold retry after each NaN; cold updates were exact on all of
    them. The price is a few active-set iterations per tick (about 25 % of the solve time on the TALOS-sized
    benchmark, whose active set barely changes between ticks).

    Tolerances: ``primal_tol`` defaults to 1e-9 (daqp's own default, 1e-6, lets a returned point violate a
    constraint by up to 1e-6). A singular ``H`` is handled by daqp's automatic proximal-point iterations
    (``eps_prox < 0``, daqp's default); their stopping tolerance is 1e-6 unless ``dual_tol`` differs from
    daqp's default, in which case it is ``0.1 * dual_tol``: we set ``dual_tol = 1e-10``, which makes those
    solves exact to about 1e-10 (measured: residuals off by up to 1e-7 with daqp's defaults on the
    hierarchical levels of ``tests/qp``). Any daqp setting can be passed by keyword, see
    ``daqp.Model().settings``.

    State: with an unchanged structure, a solve updates the workspace (no set-up) and resets the working set,
    which makes a positive-definite solve independent of the previous ones. daqp's proximal iterations
    (singular ``H``) however start from the previous iterate: a reused workspace then returns another point
    of the optimal face, and the accuracy of later solves drifted to about 1e-8 over 200 repeated
    hierarchical solves (fresh: 1e-12). ``fresh_setup=True`` sets daqp up at every solve (our buffers are
    still reused), for about 20 % more time, and makes every solve independent of the history; the
    hierarchical solver uses it for its level QPs.

    Args:
        fresh_setup: set daqp up from scratch at every solve instead of updating the workspace.
        **settings: daqp settings, e.g. ``primal_tol=1e-9``, ``iter_limit=1000``.

    Raises:
        ValueError: an unknown setting name (the message lists the valid ones).
    """

    name = "daqp"

    def __init__(self, *, fresh_setup: bool = False, **settings: float):
        valid = daqp.Model().settings
        unknown = sorted(set(settings) - set(valid))
        if unknown:
            raise QPError(f"DaqpSolver: unknown setting(s) {unknown}; valid: {', '.join(sorted(valid))}")
        self.settings: dict[str, float] = {**_DEFAULTS, **settings}
        self.fresh_setup = bool(fresh_setup)
        self.reset()

    def reset(self) -> None:
        """Drop the workspace: the next solve sets daqp up from scratch."""
        self._model: Any = None
        self._key: tuple[int, int, int, bool] | None = None

    def _allocate(self, key: tuple[int, int, int, bool]) -> None:
        n, m_eq, m_in, box = key
        nb = n if box else 0
        self._A = np.zeros((m_eq + m_in, n))
        self._bu = np.zeros(nb + m_eq + m_in)
        self._bl = np.zeros(nb + m_eq + m_in)
        self._sense = np.full(nb + m_eq + m_in, _SENSE_INEQUALITY, dtype=np.intc)
        self._sense[nb : nb + m_eq] = _SENSE_EQUALITY
        self._sense_work = self._sense.copy()  # handed to daqp, which may mark active rows in it
        self._A_eq, self._A_in = self._A[:m_eq], self._A[m_eq:]
        self._bu_box, self._bl_box = self._bu[:nb], self._bl[:nb]
        self._bu_eq, self._bl_eq = self._bu[nb : nb + m_eq], self._bl[nb : nb + m_eq]
        self._bu_in, self._bl_in = self._bu[nb + m_eq :], self._bl[nb + m_eq :]
        self._key = key
        self._model = None

    def _setup(self, p: QPProblem) -> int:
        self._model = daqp.Model()
        self._model.settings = self.settings
        np.copyto(self._sense_work, self._sense)
        flag, _ = self._model.setup(_writable(p.H), _writable(p.g), self._A, self._bu, self._bl, self._sense_work)
        return int(flag)

    def _fill(self, p: QPProblem, m_eq: int, m_in: int, box: bool) -> None:
        if box:
            np.copyto(self._bu_box, p.ub)
            np.copyto(self._bl_box, p.lb)
        if m_eq:
            np.copyto(self._A_eq, p.A_eq)
            np.copyto(self._bu_eq, p.b_eq)
            np.copyto(self._bl_eq, p.b_eq)
        if m_in:
            np.copyto(self._A_in, p.C)
            np.copyto(self._bu_in, p.u)
            np.copyto(self._bl_in, p.l)

    def solve(self, problem: QPProblem) -> QPResult:
        """Solve ``problem`` with daqp; see the class docstring for the layout."""
        p = problem
        m_eq = 0 if p.A_eq is None else p.A_eq.shape[0]
        m_in = 0 if p.C is None else p.C.shape[0]
        box = p.lb is not None
        key = (p.H.shape[0], m_eq, m_in, box)
        if key != self._key:
            self._allocate(key)
        self._fill(p, m_eq, m_in, box)
        if self._model is None or self.fresh_setup:
            flag = self._setup(p)
        else:
            kwargs: dict[str, Any] = {"H": _writable(p.H), "f": _writable(p.g)}
            if m_eq + m_in:
                kwargs["A"] = self._A
            if self._bu.shape[0]:
                np.copyto(self._sense_work, self._sense)  # reset the working set (no warm start)
                kwargs["bupper"] = self._bu
                kwargs["blower"] = self._bl
                kwargs["sense"] = self._sense_work
            flag = int(self._model.update(**kwargs))
        if flag < 0:
            self._model = None  # set up again next time
            return QPResult.failure(DAQP_EXIT_FLAGS.get(flag, QPStatus.NUMERICAL), solver=self.name, raw_status=flag)
        x, fval, exitflag, info = self._model.solve()
        status = DAQP_EXIT_FLAGS.get(int(exitflag), QPStatus.NUMERICAL)
        iterations = int(info["iterations"])
        if status is QPStatus.OPTIMAL and not np.isfinite(x).all():
            status = QPStatus.NUMERICAL
        if status is not QPStatus.OPTIMAL:
            return QPResult.failure(status, solver=self.name, raw_status=int(exitflag), iterations=iterations)
        # daqp.Model.solve returns a fresh copy of its iterate: the result may own it.
        return QPResult(x, status, iterations, float(fval), self.name, int(exitflag),
                        _working_set(info["lam"], p.H.shape[0] if box else 0, m_eq))


def _working_set(lam: npt.NDArray[np.float64], n_box: int, m_eq: int) -> tuple:
    """`QPResult.working_set` from daqp's multipliers ``lam`` (its bound layout: ``n_box`` simple bounds, then the
    ``m_eq`` equality rows, then the inequality rows; positive at an upper bound, negative at a lower one)."""
    box, ineq = lam[:n_box], lam[n_box + m_eq:]
    return (np.flatnonzero(ineq > 0.0), np.flatnonzero(ineq < 0.0), np.flatnonzero(box > 0.0),
            np.flatnonzero(box < 0.0))


def _writable(array: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """daqp's typed memoryviews refuse read-only buffers: copy those (only those)."""
    return array if array.flags.writeable else array.copy()
