"""ProxQP backend (proxsuite, augmented Lagrangian, Bambade et al. 2022), dense workspace."""

from __future__ import annotations

from typing import Any

import numpy as np
from proxsuite import proxqp

from wbcbench.errors import QPError
from wbcbench.qp.problem import QPProblem
from wbcbench.qp.result import QPResult, QPStatus
from wbcbench.qp.solver import QPSolver

__all__ = ["ProxsuiteSolver", "PROXSUITE_STATUSES"]

PROXSUITE_STATUSES: dict[Any, QPStatus] = {
    proxqp.PROXQP_SOLVED: QPStatus.OPTIMAL,
    proxqp.PROXQP_MAX_ITER_REACHED: QPStatus.MAX_ITER,
    proxqp.PROXQP_PRIMAL_INFEASIBLE: QPStatus.INFEASIBLE,
    proxqp.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE: QPStatus.INFEASIBLE,
    proxqp.PROXQP_DUAL_INFEASIBLE: QPStatus.UNBOUNDED,
    proxqp.PROXQP_NOT_RUN: QPStatus.NUMERICAL,
}
"""proxsuite ``QPSolverOutput`` -> :class:`QPStatus`."""

EPS_ABS_DEFAULT = 1e-9
"""Absolute stopping tolerance on the primal and dual residuals (proxsuite's default is 1e-5).

At its default tolerance proxsuite was measured up to 3e-2 away from the exact solution on TALOS-sized
problems (62 variables), and up to 1e-4 on the random TALOS-sized problems of known solution of
``tests/qp``; at 1e-9 (with the duality-gap check) it is within 1e-8 of them (the tests check 1e-6), for a
few more iterations.
"""


class ProxsuiteSolver(QPSolver):
    """QP backend on ``proxsuite.proxqp.dense.QP``, used as a workspace (init once, update per call).

    The workspace is created and initialised (with its Ruiz preconditioner) when the structure (n, m_eq,
    m_in, box) changes; otherwise each call updates the matrices in place and solves warm-started from the
    previous primal-dual solution (``WARM_START_WITH_PREVIOUS_RESULT``). A solve that fails on an updated
    workspace is retried once on a fresh one within the same call (warm starts across large jumps in the
    data were measured to end in false "primal infeasible" reports); after a failure the next call also
    starts fresh.

    Known limits (proxsuite 0.8): its infeasibility detection misses simple infeasible problems (e.g. a box
    ``x0 <= 1`` against a row ``x0 >= 2``), which then end in :attr:`QPStatus.MAX_ITER` (still ``x = None``);
    without the duality-gap check it may report "solved" points whose objective is off by 1e-4 on small
    degenerate problems, hence ``check_duality_gap=True`` by default. daqp reports such infeasible problems
    infeasible and is the default backend.

    Args:
        eps_abs: absolute residual tolerance, see :data:`EPS_ABS_DEFAULT`.
        eps_rel: relative residual tolerance (0 disables it).
        max_iter: iteration limit (1000: a real-time budget; warm-started TALOS-sized solves take under 20).
        warm_start: warm-start from the previous result when the structure is unchanged.
        check_duality_gap: also require the duality gap below ``eps_abs`` (tighter objective, more iterations).
        **settings: any other ``proxqp.Settings`` attribute, e.g. ``eps_primal_inf=1e-12``.

    Raises:
        ValueError: a bad value or an unknown setting name (the message lists the valid ones).
    """

    name = "proxsuite"

    def __init__(
        self,
        *,
        eps_abs: float = EPS_ABS_DEFAULT,
        eps_rel: float = 0.0,
        max_iter: int = 1000,
        warm_start: bool = True,
        check_duality_gap: bool = True,
        **settings: Any,
    ):
        if not eps_abs > 0.0:
            raise QPError(f"ProxsuiteSolver: eps_abs must be > 0, got {eps_abs}")
        if not eps_rel >= 0.0:
            raise QPError(f"ProxsuiteSolver: eps_rel must be >= 0, got {eps_rel}")
        if max_iter < 1:
            raise QPError(f"ProxsuiteSolver: max_iter must be >= 1, got {max_iter}")
        self.eps_abs = float(eps_abs)
        self.eps_rel = float(eps_rel)
        self.max_iter = int(max_iter)
        self.warm_start = bool(warm_start)
        self.check_duality_gap = bool(check_duality_gap)
        valid = sorted(a for a in dir(proxqp.Settings()) if not a.startswith("_"))
        unknown = sorted(set(settings) - set(valid))
        if unknown:
            raise QPError(f"ProxsuiteSolver: unknown setting(s) {unknown}; valid: {', '.join(valid)}")
        self.settings: dict[str, Any] = dict(settings)
        self.reset()

    def reset(self) -> None:
        """Drop the workspace: the next solve initialises a fresh one."""
        self._qp: Any = None
        self._key: tuple[int, int, int, bool] | None = None

    def _init(self, p: QPProblem, key: tuple[int, int, int, bool]) -> None:
        n, m_eq, m_in, box = key
        qp = proxqp.dense.QP(n, m_eq, m_in, box)
        s = qp.settings
        s.eps_abs = self.eps_abs
        s.eps_rel = self.eps_rel
        s.max_iter = self.max_iter
        s.check_duality_gap = self.check_duality_gap
        s.eps_duality_gap_abs = self.eps_abs
        s.verbose = False
        for key, value in self.settings.items():
            setattr(s, key, value)
        s.initial_guess = (
            proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            if self.warm_start
            else proxqp.InitialGuess.EQUALITY_CONSTRAINED_INITIAL_GUESS
        )
        if box:
            qp.init(p.H, p.g, p.A_eq, p.b_eq, p.C, p.l, p.u, p.lb, p.ub)
        else:
            qp.init(p.H, p.g, p.A_eq, p.b_eq, p.C, p.l, p.u)
        self._qp = qp
        self._key = key

    def solve(self, problem: QPProblem) -> QPResult:
        """Solve ``problem`` with ProxQP; see the class docstring for the workspace policy."""
        p = problem
        m_eq = 0 if p.A_eq is None else p.A_eq.shape[0]
        m_in = 0 if p.C is None else p.C.shape[0]
        box = p.lb is not None
        key = (p.H.shape[0], m_eq, m_in, box)
        qp = self._qp
        fresh = qp is None or key != self._key
        if fresh:
            self._init(p, key)
            qp = self._qp
        elif box:
            qp.update(p.H, p.g, p.A_eq, p.b_eq, p.C, p.l, p.u, p.lb, p.ub)
        else:
            qp.update(p.H, p.g, p.A_eq, p.b_eq, p.C, p.l, p.u)
        qp.solve()
        info = qp.results.info
        status = PROXSUITE_STATUSES.get(info.status, QPStatus.NUMERICAL)
        x = qp.results.x
        if status is QPStatus.OPTIMAL and not np.isfinite(x).all():
            status = QPStatus.NUMERICAL
        if status is not QPStatus.OPTIMAL:
            self._qp = None  # initialise a fresh workspace next time
            if not fresh:  # a warm-started (updated) workspace failed: retry from a fresh one once
                return self.solve(problem)
            return QPResult.failure(status, solver=self.name, raw_status=info.status.name, iterations=int(info.iter))
        # results.x is a view into the workspace, overwritten by the next solve: the result owns a copy.
        return QPResult(np.array(x), status, int(info.iter), float(info.objValue), self.name, info.status.name)
