"""Hierarchical (lexicographic) least squares: strict priorities between levels, under hard bounds.

Problem (levels k = 1..K in priority order, variables x (n,), hard bounds ``lb <= x <= ub``)::

    level k:  min  sum_{i in k} w_i ||A_i x - b_i||^2 + sum_{j in k} w_j ||s_j||^2
              s.t. lower_j <= C_j x - s_j <= upper_j          (inequality tasks of level k, slacks s_j)
                   x optimal for every level above k
                   lb <= x <= ub

then ``min ||x||^2`` over the remaining optimal set (an implicit last level that makes x unique).

Optimal sets. The optimal ``(A_i x, s_j)`` of a level is unique (the cost is strictly convex in them), and a
row left violated (``s_j != 0``) sits exactly at ``C_j x = upper_j + s_j`` (or ``lower_j + s_j``) on the whole
optimal set, else its slack could shrink. So the levels below must keep (i) the equality rows and the
violated inequality rows at their values, which they do by moving only in an orthonormal basis ``Z``
(n, d) of the null space of those rows, and (ii) the satisfied inequality rows satisfied, carried down as
inequality rows ``lower_j + s_j <= C_j x <= upper_j + s_j`` (slacks below ``1e-6`` count as satisfied).

Method. Level k works on ``x + Z z``:

- fast path: the least-squares step ``z`` of its equality rows in the null space (pivoted QR of
  ``(A_k Z)^T``, optional damping); if the new point satisfies the bounds, the carried rows and the level's
  own inequality tasks (within ``feasibility_tol``), it is the level's optimum (the slacks are zero);
- otherwise a QP in ``(z, s)`` through a :class:`~wbcbench.qp.QPSolver` backend (daqp by default), with
  the bounds and carried rows as inequality rows in ``z``.

Then ``Z`` shrinks to the null space of the rows this level fixed (rank-revealing, threshold
``rank_tol * ||rows||_F``). A level whose target is out of reach is met as well as possible in the
least-squares sense and reported ``met = False``; the levels below still use whatever freedom is left.

Closed form (``fast_path``, no damping): a hierarchy of equality tasks whose first levels are met exactly and
whose next level, if any, takes all the freedom left (the IK's feet, CoM, waist, then posture) is one
least-squares problem with equality constraints, solved with one LAPACK call and accepted when the bounds do
not bind and the rank tests pass (``HierarchicalSolver._solve_equalities``); otherwise the cascade above runs.
The same levels handed again (a tuple of :class:`Level`, rows updated in place) reuse their checks and layout.

Damping: ``damping = lambda > 0`` adds ``lambda^2 ||z||^2`` to every level's cost (a damped
pseudo-inverse on the fast path, the same Tikhonov term in the QP), trading exactness (bias about
``lambda^2 / sigma^2``) for bounded steps near singular configurations. With ``lambda = 0`` (default) each
level is solved exactly; a singular level Hessian in the QP path is handled by daqp's proximal iterations
(``eps_prox = 1e-3``, see :data:`_LEVEL_OPTIONS`).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.linalg import lapack
from scipy.optimize import nnls

from wbcbench.errors import QPError
from wbcbench.qp import kernels
from wbcbench.qp._nullspace import least_squares_step, project
from wbcbench.qp.levels import EqualityTask, InequalityTask, Level, Task
from wbcbench.qp.problem import QPProblem
from wbcbench.qp.registry import make_solver, solver_names
from wbcbench.qp.result import QPResult, QPStatus
from wbcbench.qp.solver import QPSolver

__all__ = ["HierarchicalSolver", "HierarchicalResult", "LevelReport", "LevelPath"]

FloatArray = npt.NDArray[np.float64]


_CLOSED_FORM_RANK_TOL = 1e-6
"""Relative rank threshold of the closed-form path (see ``HierarchicalSolver._solve_equalities``): a thousand
times the cascade's default ``rank_tol``, so that the two agree on which levels have full rank."""

_SLACK_AS_EQUALITY = 1e-6
"""Optimal slacks above this (or 1000 x feasibility_tol), in weighted task units, turn their inequality rows
into equality rows for the levels below; smaller ones are within the backends' accuracy."""

_LEVEL_OPTIONS: dict[str, dict[str, Any]] = {"daqp": {"fresh_setup": True, "eps_prox": 1e-3}}
"""Backend options of the level QPs (user ``solver_options`` override them). daqp: results independent of
the previous tick (``fresh_setup``, see DaqpSolver), so that a reused solver returns what a fresh one does;
and forced proximal iterations with ``eps_prox = 1e-3``: level Hessians are singular (rank of the level's
rows), and daqp's automatic regularisation (1e-6) reported 1.5 % of the level QPs of TALOS-like stacks with
binding bounds infeasible (including a real IK tick), against 0.03 % at 1e-3, at the same speed and
accuracy (the proximal iterations converge to an exact optimum). proxsuite keeps its defaults."""

_RETRY_OPTIONS: dict[str, tuple[dict[str, float], ...]] = {
    "daqp": ({"primal_tol": 1e-7}, {"eps_prox": 1e-1}),
    "proxsuite": ({"eps_abs": 1e-7, "eps_primal_inf": 1e-12, "eps_dual_inf": 1e-12},),
}
"""Backend options of the retries of a failed level QP, in order. daqp: a 100x looser primal tolerance, then
a 100x larger proximal regularisation (on 15 failed level QPs out of 7500 of TALOS-like stacks with hard
binding bounds, the first retry solved 14, the second the last one). proxsuite: a looser tolerance and a
much stricter infeasibility certificate (its default, 1e-4, fires on feasible degenerate level QPs)."""


class LevelPath(enum.Enum):
    """How a level was solved."""

    NULLSPACE = "nullspace"
    """Closed form in the null space of the levels above: no bound or inequality binds."""
    QP = "qp"
    """Constrained least squares through a QP backend (a bound or inequality binds)."""
    LOCKED = "locked"
    """No free direction left: the levels above fix x completely; the level is only evaluated."""
    FAILED = "failed"
    """The QP backend failed (after the retries): the level was skipped; x stays where the levels above put it
    (feasible), nothing is fixed for the levels below."""


@dataclass(frozen=True, slots=True)
class LevelReport:
    """What happened at one level.

    Attributes:
        index: 0-based priority (0 is the highest).
        name: the level's name.
        residual: ``sqrt(sum_i w_i ||A_i x - b_i||^2 + sum_j w_j ||violation_j||^2)`` at the returned x, in
            the tasks' (weighted) units.
        task_residuals: unweighted norm of each task's residual (equality) or violation (inequality) at the
            returned x, by task name.
        met: ``residual <= met_tol``.
        rank: number of directions this level fixes for the levels below: rank, in the null space of the
            levels above, of its equality rows and of its inequality rows left violated (0 when it only has
            satisfied inequality rows).
        freedom: dimension d of the null space left by the levels above, before this level.
        path: how the level was solved, see :class:`LevelPath`.
        qp_status: status of the level's QP when one was solved, else None.
        qp_iterations: iterations of that QP (0 when none).
        qp_attempts: 1 when the backend solved the level QP at once; more when it failed and the point of the
            levels above was checked by its KKT conditions (2: certified optimal) or the QP retried with other
            settings (0 when no QP).
    """

    index: int
    name: str
    residual: float
    task_residuals: Mapping[str, float]
    met: bool
    rank: int
    freedom: int
    path: LevelPath
    qp_status: QPStatus | None = None
    qp_iterations: int = 0
    qp_attempts: int = 0


class HierarchicalResult:
    """Solution of a hierarchical problem.

    Attributes:
        x: (n,) solution, always set (it is the best point found even when ``ok`` is False).
        levels: one :class:`LevelReport` per level, in priority order (made on first access by the closed-form
            path, which solves a tick faster than it would describe it).
        met: one bool per level, ``levels[k].met`` (available without making the reports).
        ok: True when every level and the final min-norm step were solved (no :attr:`LevelPath.FAILED`).
        bound_violation: largest violation of ``lb <= x <= ub`` before the final clip (0 when none). x is
            always clipped into the bounds; a violation above ``feasibility_tol`` only happens after a
            failed level (``ok`` False).
        final_path: how the implicit min-norm level was solved.
    """

    __slots__ = ("x", "_levels", "ok", "bound_violation", "final_path", "_met")

    def __init__(self, x: FloatArray, levels: tuple[LevelReport, ...] | Callable[[], tuple[LevelReport, ...]],
                 ok: bool, bound_violation: float, final_path: LevelPath, met: tuple[bool, ...] | None = None):
        self.x = x
        self._levels = levels
        self.ok = ok
        self.bound_violation = bound_violation
        self.final_path = final_path
        self._met = met

    @property
    def levels(self) -> tuple[LevelReport, ...]:
        if callable(self._levels):
            self._levels = self._levels()
        return self._levels

    @property
    def met(self) -> tuple[bool, ...]:
        if self._met is None:
            self._met = tuple(r.met for r in self.levels)
        return self._met

    def __repr__(self) -> str:
        return (f"HierarchicalResult(ok={self.ok}, final_path={self.final_path.value}, "
                f"bound_violation={self.bound_violation:.3g}, met={self.met})")

    def report(self) -> str:
        """A per-level status table (level, path, rank, freedom, residual, met, tasks)."""
        lines = [f"{'lvl':>3} {'path':<9} {'rank':>4} {'free':>4} {'residual':>11} met  tasks"]
        for r in self.levels:
            tasks = ", ".join(f"{k}={v:.3g}" for k, v in r.task_residuals.items())
            lines.append(
                f"{r.index:>3} {r.path.value:<9} {r.rank:>4} {r.freedom:>4} {r.residual:>11.4g} "
                f"{'yes' if r.met else 'NO ':<4} {tasks}"
            )
        return "\n".join(lines)


_REPORT_SLOTS = tuple(getattr(LevelReport, f.name).__set__ for f in fields(LevelReport))


def _level_report(index: int, name: str, residual: float, task_residuals: Mapping[str, float], met: bool, rank: int,
                  freedom: int, path: LevelPath, qp_status: QPStatus | None, qp_iterations: int,
                  qp_attempts: int) -> LevelReport:
    """``LevelReport(...)`` without the frozen dataclass' ``__init__``, which sets each field through
    ``object.__setattr__``: the slot descriptors set them directly (half the time; the closed-form path makes
    one per level every tick)."""
    report = object.__new__(LevelReport)
    s = _REPORT_SLOTS
    s[0](report, index)
    s[1](report, name)
    s[2](report, residual)
    s[3](report, task_residuals)
    s[4](report, met)
    s[5](report, rank)
    s[6](report, freedom)
    s[7](report, path)
    s[8](report, qp_status)
    s[9](report, qp_iterations)
    s[10](report, qp_attempts)
    return report


@dataclass(slots=True)
class _Carried:
    """Inequality rows of the levels above, relaxed by their optimal slacks: lo <= C x <= hi."""

    C: FloatArray
    lo: FloatArray
    hi: FloatArray


class HierarchicalSolver:
    """Lexicographic least-squares solver over priority levels, under hard bounds (see the module docstring).

    Args:
        n: number of variables (e.g. nv = 38 joint velocities for TALOS, rad/s and m/s).
        solver: registry name of the QP backend for the constrained levels (``"daqp"`` or ``"proxsuite"``).
        solver_options: keyword options of that backend.
        damping: Tikhonov factor lambda >= 0 on every level's step (0: exact).
        rank_tol: relative rank threshold: a direction counts when its pivot exceeds
            ``rank_tol * ||A_k||_F`` (Frobenius norm of the level's weighted equality rows).
        feasibility_tol: absolute tolerance on bounds and inequality rows when accepting a fast-path step;
            the carried inequality rows are relaxed by it (x itself is clipped into the bounds after every
            level, so the returned x always satisfies them exactly).
        met_tol: a level is reported met when its residual is at most this (weighted task units).
        fast_path: use the closed-form null-space step when nothing binds (False: always a QP; for tests and
            benchmarks).

    One instance keeps one QP backend per level (buffers reused from tick to tick, each solve independent of
    the previous one, see :data:`_LEVEL_OPTIONS`); use one instance per hierarchy. Not thread-safe.

    Degenerate level QPs: level Hessians are singular (rank of the level's rows, 1 for a CoM-height level over
    26 free directions), and when a level above drives joints to their bounds the level QP sits at a
    degenerate vertex (more active bounds than free directions), often with ``z = 0`` as its only feasible
    point; daqp and proxsuite then may report it infeasible (about one level QP in 500 on TALOS-like stacks
    with hard binding bounds, and every tick of an IK asked for a CoM 60 cm out of reach). So when the
    backend fails, ``z = 0`` (stay where the levels above put x) is checked by its KKT conditions
    (:func:`_kkt_optimal`) and accepted when optimal; otherwise the QP is retried with other settings
    (:data:`_RETRY_OPTIONS`). A level that still fails is reported :attr:`LevelPath.FAILED` and skipped: x
    stays where the levels above put it (feasible, every level above still optimal), the levels below go on,
    and ``ok`` is False.
    """

    def __init__(
        self,
        n: int,
        *,
        solver: str = "daqp",
        solver_options: Mapping[str, Any] | None = None,
        damping: float = 0.0,
        rank_tol: float = 1e-9,
        feasibility_tol: float = 1e-9,
        met_tol: float = 1e-6,
        fast_path: bool = True,
    ):
        if int(n) != n or n < 1:
            raise QPError(f"HierarchicalSolver: n must be a positive integer, got {n!r}")
        if solver not in solver_names():
            raise QPError(f"HierarchicalSolver: unknown QP solver {solver!r}; valid: {', '.join(solver_names())}")
        for key, value in (("damping", damping), ("rank_tol", rank_tol), ("feasibility_tol", feasibility_tol),
                           ("met_tol", met_tol)):
            if not (math.isfinite(value) and value >= 0.0):
                raise QPError(f"HierarchicalSolver: {key} must be finite and >= 0, got {value!r}")
        self.n = int(n)
        self.solver_name = solver
        self.solver_options = dict(solver_options or {})
        make_solver(solver, **self.solver_options)  # fail now on bad options
        self.damping = float(damping)
        self.rank_tol = float(rank_tol)
        self.feasibility_tol = float(feasibility_tol)
        self.met_tol = float(met_tol)
        self.fast_path = bool(fast_path)
        self._solvers: dict[tuple[int | str, int], QPSolver] = {}
        self._checked_levels: tuple[Level, ...] | None = None
        self._checked_bounds: tuple[FloatArray | None, FloatArray | None] = (None, None)
        self._plan_levels: tuple[Level, ...] | None = None
        self._plan: _ClosedFormPlan | None = None

    # ------------------------------------------------------------------ input

    def _levels(self, levels: Sequence[Level | Sequence[Task] | Task]) -> tuple[Level, ...]:
        # A tuple of Level objects is immutable (frozen levels, task tuples, frozen tasks): the one checked
        # last time needs no new check (a controller hands the same levels every tick, their rows updated in
        # place).
        if levels is self._checked_levels:
            return levels
        out = []
        for k, level in enumerate(levels):
            if isinstance(level, Level):
                out.append(level)
            elif isinstance(level, (EqualityTask, InequalityTask)):
                out.append(Level((level,)))
            else:
                try:
                    out.append(Level(tuple(level), name=f"level{k}"))
                except ValueError as exc:
                    raise QPError(f"HierarchicalSolver: level {k}: {exc}") from None
        seen: dict[str, int] = {}
        for k, level in enumerate(out):
            for task in level.tasks:
                if task.name in seen:
                    raise QPError(
                        f"HierarchicalSolver: task name '{task.name}' appears twice (levels {seen[task.name]} and {k})"
                    )
                seen[task.name] = k
                if task.n_cols != self.n:
                    raise QPError(
                        f"HierarchicalSolver: level {k} ('{level.name}'), task '{task.name}': "
                        f"{task.n_cols} columns, expected n = {self.n}"
                    )
        out = tuple(out)
        if type(levels) is tuple and all(a is b for a, b in zip(levels, out)):
            self._checked_levels = levels
        return out

    def _bounds(self, lower: Any, upper: Any) -> tuple[FloatArray, FloatArray]:
        # the usual case: the caller's (n,) float64 arrays (shape and type checked once per pair of arrays), no
        # NaN and ordered: one comparison
        if lower is self._checked_bounds[0] and upper is self._checked_bounds[1] and lower is not None:
            if kernels.bounds_ordered(lower, upper):
                return lower, upper
        elif (type(lower) is np.ndarray and type(upper) is np.ndarray and lower.dtype == upper.dtype == np.float64
              and lower.shape == upper.shape == (self.n,)):
            self._checked_bounds = (lower, upper)
            if kernels.bounds_ordered(lower, upper):
                return lower, upper
        bounds = []
        for value, fill, side in ((lower, -np.inf, "lower"), (upper, np.inf, "upper")):
            if value is None:
                bounds.append(np.full(self.n, fill))
                continue
            array = np.asarray(value, dtype=np.float64)
            if array.shape != (self.n,):
                raise QPError(f"HierarchicalSolver: {side} bounds must have shape ({self.n},), got {array.shape}")
            bounds.append(array)
        lb, ub = bounds
        if (lb <= ub).all():  # no NaN, ordered: the usual case in one comparison
            return lb, ub
        for array, side in ((lb, "lower"), (ub, "upper")):
            if np.isnan(array).any():
                raise QPError(f"HierarchicalSolver: {side} bounds contain NaN")
        bad = np.flatnonzero(lb > ub)
        if bad.size:
            i = int(bad[0])
            raise QPError(f"HierarchicalSolver: lower bound above upper bound for variable {i} ({lb[i]} > {ub[i]})")
        return lb, ub

    def _solver(self, key: int | str, attempt: int) -> QPSolver:
        solver = self._solvers.get((key, attempt))
        if solver is None:
            options = {**_LEVEL_OPTIONS.get(self.solver_name, {}), **self.solver_options}
            if attempt:
                options.update(_RETRY_OPTIONS[self.solver_name][attempt - 1])
            solver = self._solvers[(key, attempt)] = make_solver(self.solver_name, **options)
        return solver

    def _solve_qp(self, key: int | str, problem: QPProblem, stay: FloatArray) -> tuple[QPResult, int]:
        """Solve a level QP; on failure, certify ``stay`` (the point of the levels above) by its KKT conditions,
        then retry with :data:`_RETRY_OPTIONS`. Returns (result, attempts: backend calls plus the check)."""
        result = self._solver(key, 0).solve(problem)
        if result.x is not None:
            return result, 1
        if _kkt_optimal(problem, stay, self.feasibility_tol):
            return QPResult(stay, QPStatus.OPTIMAL, 0, problem.objective(stay), self.solver_name, "kkt-certified"), 2
        for attempt, _ in enumerate(_RETRY_OPTIONS.get(self.solver_name, ()), start=1):
            result = self._solver(key, attempt).solve(problem)
            if result.x is not None:
                break
        return result, 2 + len(_RETRY_OPTIONS.get(self.solver_name, ()))

    # ------------------------------------------------------------------ solve

    def solve(
        self,
        levels: Sequence[Level | Sequence[Task] | Task],
        lower: Any = None,
        upper: Any = None,
    ) -> HierarchicalResult:
        """Solve the hierarchy.

        Args:
            levels: in priority order; each a :class:`Level`, a sequence of tasks, or a single task.
            lower: (n,) hard lower bounds on x (``-inf`` allowed), None for none.
            upper: (n,) hard upper bounds on x (``+inf`` allowed), None for none.

        Raises:
            ValueError: an empty level, a task name used twice, a task whose column count is not n, bad bounds.
        """
        levels = self._levels(levels)
        lb, ub = self._bounds(lower, upper)
        if self.fast_path and self.damping == 0.0:
            result = self._solve_equalities(levels, lb, ub)
            if result is not None:
                return result
        st = _State(self.n, lb, ub, self.feasibility_tol)
        steps = [self._level(k, level, st) for k, level in enumerate(levels)]
        final_path = self._min_norm(st)
        x = st.x
        violation = float(max(0.0, np.max(lb - x), np.max(x - ub)))
        if violation > 0.0:
            x = np.clip(x, lb, ub)
        ok = final_path is not LevelPath.FAILED and all(step[0] is not LevelPath.FAILED for step in steps)
        reports = tuple(self._report(k, level, x, *steps[k]) for k, level in enumerate(levels))
        return HierarchicalResult(x, reports, ok, violation, final_path)

    def _solve_equalities(self, levels: tuple[Level, ...], lb: FloatArray, ub: FloatArray) -> HierarchicalResult | None:
        """The closed-form path of a hierarchy of equality tasks whose bounds do not bind; None when it does not
        apply (then the level-by-level cascade runs).

        It applies when the first levels' rows, stacked (``P``, at most n rows), have full row rank, and the
        levels after them are either none or one level that uses up all the freedom left (full column rank in
        the null space of ``P``) followed by levels that can only be evaluated. Every row of ``P`` is then met
        exactly, so the optimal set of those levels is ``{P x = b_P}`` and the hierarchy is one problem:

        - no level after ``P``: ``x`` = the minimum-norm solution of ``P x = b_P`` (the implicit last level),
          one LQ factorisation (LAPACK ``dgels``);
        - one level ``(A, c)`` after: ``min ||A x - c||  s.t.  P x = b_P``, a least-squares problem with
          equality constraints, one generalised RQ factorisation (LAPACK ``dgglse``).

        The answer is the cascade's (to rounding) when it satisfies the bounds within ``feasibility_tol``, which
        is checked; otherwise, or when a rank test fails, None. The rank tests are stricter than the cascade's:
        every diagonal entry of the triangular factors must exceed ``_CLOSED_FORM_RANK_TOL`` (1e-6) times the
        Frobenius norm of its rows (the cascade counts a direction from ``rank_tol`` = 1e-9 of its level's norm,
        on a pivoted factorisation); a hierarchy nearer to rank deficiency takes the cascade.
        """
        n = self.n
        plan = self._plan if levels is self._plan_levels else None
        if plan is None:
            plan = _ClosedFormPlan.of(levels, n)
            if levels is self._checked_levels:  # the same immutable levels again next tick: keep the plan
                self._plan_levels, self._plan = levels, plan
        if plan.n_prefix == 0:
            return None
        counts, n_prefix, r = plan.counts, plan.n_prefix, plan.r
        if plan.A is not None:  # the tasks' rows lie one after the other in memory: views, no copy
            A, b, P, b_P, A_k, c_k = plan.A, plan.b, plan.P, plan.b_P, plan.A_k, plan.c_k
        else:
            A = np.concatenate([t.A if w == 1.0 else math.sqrt(w) * t.A for t, w in plan.tasks]) if \
                len(plan.tasks) > 1 else plan.tasks[0][0].A
            b = np.concatenate([t.b if w == 1.0 else math.sqrt(w) * t.b for t, w in plan.tasks]) if \
                len(plan.tasks) > 1 else plan.tasks[0][0].b
            k_end = r + counts[n_prefix] if n_prefix < len(counts) else r
            P, b_P, A_k, c_k = A[:r], b[:r], A[r:k_end], b[r:k_end]
        d = n - r
        status = 0
        if n_prefix < len(levels) and d:
            # a posture-like level (one non-zero per row): the compiled projection, else the general LAPACK path
            x = np.empty(n)
            status = kernels.selection_lsq_into(P, b_P, A_k, c_k, _CLOSED_FORM_RANK_TOL, x)
            final_path = LevelPath.LOCKED
        if status == 1:
            pass
        elif n_prefix == len(levels):
            tol = _CLOSED_FORM_RANK_TOL * _frobenius(P)
            # min ||x|| s.t. P x = b_P: LQ of P (full row rank), L on and below the diagonal of lq[:r, :r]
            padded = np.zeros(n)
            padded[:r] = b_P
            lq, sol, info = lapack.dgels(P, padded)
            if info != 0 or not np.abs(lq.diagonal()[:r]).min() > tol:
                return None
            x = sol
            final_path = LevelPath.NULLSPACE if d else LevelPath.LOCKED
        else:
            # A_k is (m_k, n) with m_k > d: T (d, d) from A_k in the null space of P, R (r, r) from P
            tol = _CLOSED_FORM_RANK_TOL * _frobenius(P)
            T, R, _, x, info = lapack.dgglse(A_k, P, c_k, b_P)
            if info != 0 or not np.abs(R.diagonal(d)).min() > tol:
                return None
            if d and not np.abs(T.diagonal()[:d]).min() > _CLOSED_FORM_RANK_TOL * _frobenius(A_k):
                return None
            final_path = LevelPath.LOCKED
        ftol = self.feasibility_tol
        sums = None
        # one call for the bound test and the residuals
        sums_, level_sq = plan.sums
        high, low = kernels.bounds_and_residuals(A, b, x, plan.starts, plan.block_level, lb, ub, sums_, level_sq)
        if not (high <= ftol and low <= ftol):  # a bound binds (or x is not finite)
            if not np.isfinite(x).all():
                for level in levels:  # invalid rows handed over unchecked: say which
                    for task in level.tasks:
                        if type(task) is EqualityTask:
                            task._validate()
            return None
        violation = float(max(0.0, low, high))
        if violation > 0.0:
            x = np.clip(x, lb, ub)
        else:
            sums = sums_.tolist()
            if plan.unit:  # every task of weight 1: the level sums are the residuals, no loop
                met_tol = self.met_tol
                task_sq, totals = sums, level_sq.tolist()
                return HierarchicalResult(x, self._closed_form_reports(levels, plan, task_sq, totals), True,
                                          violation, final_path, tuple([math.sqrt(t) <= met_tol for t in totals]))
        if sums is None:
            # reports: residuals of every task at x, rank and freedom of every level
            e = A @ x
            e -= b
            e *= e
            sums = np.add.reduceat(e, plan.starts).tolist()
        # residual of every level (cheap); the reports themselves are made when asked for
        task_sq: list[float] = []
        totals: list[float] = []
        i = 0
        for level in levels:
            total = 0.0
            for task in level.tasks:
                w = task.weight
                if w == 1.0:
                    sq = sums[i]
                    i += 1
                else:  # weighted rows were scaled; weight 0 has no rows: evaluate it directly
                    if w > 0.0:
                        i += 1
                    res = task.residual(x)
                    sq = float(res @ res)
                task_sq.append(sq)
                total += w * sq
            totals.append(total)
        met_tol = self.met_tol
        met = tuple(math.sqrt(t) <= met_tol for t in totals)
        return HierarchicalResult(x, self._closed_form_reports(levels, plan, task_sq, totals), True, violation,
                                  final_path, met)

    def _closed_form_reports(self, levels: tuple[Level, ...], plan: _ClosedFormPlan, task_sq: list[float],
                             totals: list[float]) -> Callable[[], tuple[LevelReport, ...]]:
        """The reports of a closed-form solve, made when first asked for: per task its squared residual
        (``task_sq``, in level order), per level its weighted sum (``totals``)."""
        n, n_prefix, counts, met_tol = self.n, plan.n_prefix, plan.counts, self.met_tol

        def reports() -> tuple[LevelReport, ...]:
            out = []
            freedom = n
            sq_iter = iter(task_sq)
            for k, level in enumerate(levels):
                task_residuals = {task.name: math.sqrt(next(sq_iter)) for task in level.tasks}
                residual = math.sqrt(totals[k])
                if k < n_prefix:
                    rank, path = counts[k], LevelPath.NULLSPACE
                elif freedom:  # the level after P takes all the freedom left
                    rank, path = freedom, LevelPath.NULLSPACE
                else:
                    rank, path = 0, LevelPath.LOCKED
                out.append(_level_report(k, level.name, residual, task_residuals, residual <= met_tol, rank, freedom,
                                         path, None, 0, 0))
                freedom -= rank
            return tuple(out)

        return reports

    def _level(self, k: int, level: Level, st: _State) -> tuple[LevelPath, int, int, QPStatus | None, int, int]:
        """Solve one level in place on ``st``; returns (path, rank, freedom, qp status, iterations, attempts)."""
        A, b, own = _stack(level)
        freedom = st.d
        if st.d == 0 or (A is None and own is None):
            if own is not None:
                st.carry(own, _violation(own, st.x))
            return (LevelPath.LOCKED if st.d == 0 else LevelPath.NULLSPACE), 0, freedom, None, 0, 0

        proj = None
        candidate = st.x
        if A is not None:
            r = b - A @ st.x
            M = A if st.Z is None else A @ st.Z
            proj = project(M, st.Z, self.rank_tol * _frobenius(A))
            if proj.rank:
                y = least_squares_step(proj, r, self.damping)
                candidate = st.x + proj.ZQ[:, : proj.rank] @ y

        status, iterations, attempts = None, 0, 0
        m_own = 0 if own is None else own.C.shape[0]
        if self.fast_path and st.feasible(candidate, own):
            path, slack = LevelPath.NULLSPACE, None
            st.x = np.clip(candidate, st.lb, st.ub)
        else:
            d = st.d
            H = np.zeros((d + m_own, d + m_own))
            g = np.zeros(d + m_own)
            if A is not None:
                np.matmul(M.T, M, out=H[:d, :d])
                np.matmul(M.T, -r, out=g[:d])
            diag = H.reshape(-1)[:: d + m_own + 1]
            if self.damping:
                diag[:d] += self.damping**2
            diag[d:] = 1.0
            stay = np.zeros(d + m_own)  # z = 0: the point of the levels above, with its own violations as slacks
            if m_own:
                stay[d:] = _violation(own, st.x)
            result, attempts = self._solve_qp(k, st.problem(H, g, own), stay)
            status, iterations = result.status, result.iterations
            if result.x is None:
                return LevelPath.FAILED, 0, freedom, status, iterations, attempts
            path, slack = LevelPath.QP, result.x[d:]
            st.x = np.clip(st.x + st.lift(result.x[:d]), st.lb, st.ub)

        # What the levels below must keep: the equality rows, and the inequality rows this level could not
        # satisfy (nonzero slack), at their values; the satisfied inequality rows as inequalities.
        rank = 0 if proj is None else proj.rank
        if own is not None:
            if slack is None:
                st.carry(own, None)
            else:
                # A row violated by more than the backends' accuracy keeps its value exactly (an equality
                # row, so no thin band is left for the levels below); a row within it stays an inequality,
                # shifted by its slack.
                violated = np.abs(slack) > max(_SLACK_AS_EQUALITY, 1e3 * st.tol)
                if violated.any():
                    fixed = own.C[violated] if A is None else np.vstack([A, own.C[violated]])
                    M = fixed if st.Z is None else fixed @ st.Z
                    proj = project(M, st.Z, self.rank_tol * _frobenius(fixed))
                    rank = proj.rank
                    kept = ~violated
                    if kept.any():
                        st.carry(_Carried(own.C[kept], own.lo[kept], own.hi[kept]), slack[kept])
                else:
                    st.carry(own, slack)
        if proj is not None and proj.rank:
            st.Z = proj.ZQ[:, proj.rank :]
            st.d = st.Z.shape[1]
        return path, rank, freedom, status, iterations, attempts

    def _min_norm(self, st: _State) -> LevelPath:
        """Implicit last level: ``min ||x||^2`` over the optimal set of all levels."""
        if st.d == 0:
            return LevelPath.LOCKED
        Ztx = st.x if st.Z is None else st.Z.T @ st.x
        candidate = st.x - st.lift(Ztx)
        if self.fast_path and st.feasible(candidate, None):
            st.x = candidate
            return LevelPath.NULLSPACE
        result, _ = self._solve_qp("final", st.problem(np.eye(st.d), np.array(Ztx), None), np.zeros(st.d))
        if result.x is None:
            return LevelPath.FAILED
        st.x = st.x + st.lift(result.x)
        return LevelPath.QP

    def _report(
        self,
        k: int,
        level: Level,
        x: FloatArray,
        path: LevelPath,
        rank: int,
        freedom: int,
        status: QPStatus | None,
        iterations: int,
        attempts: int,
    ) -> LevelReport:
        task_residuals: dict[str, float] = {}
        total = 0.0
        for task in level.tasks:
            e = task.residual(x) if isinstance(task, EqualityTask) else task.violation(x)
            sq = float(e @ e)
            task_residuals[task.name] = math.sqrt(sq)
            total += task.weight * sq
        residual = math.sqrt(total)
        return LevelReport(
            k, level.name, residual, task_residuals, residual <= self.met_tol, rank, freedom, path, status, iterations,
            attempts,
        )


_TINY = float(np.finfo(float).tiny)


def _frobenius(A: FloatArray) -> float:
    return max(math.sqrt(float(np.vdot(A, A))), _TINY)


def _stack(level: Level) -> tuple[FloatArray | None, FloatArray | None, _Carried | None]:
    """The level's weighted equality rows ``(A, b)`` and inequality rows (tasks of weight 0 left out)."""
    eqs = [t for t in level.tasks if type(t) is EqualityTask and t.weight > 0.0]
    ins = [t for t in level.tasks if type(t) is InequalityTask and t.weight > 0.0]
    A = b = own = None
    if len(eqs) == 1 and eqs[0].weight == 1.0:
        A, b = eqs[0].A, eqs[0].b
    elif eqs:
        sw = [math.sqrt(t.weight) for t in eqs]
        A = np.vstack([w * t.A for w, t in zip(sw, eqs)])
        b = np.concatenate([w * t.b for w, t in zip(sw, eqs)])
    if len(ins) == 1 and ins[0].weight == 1.0:
        own = _Carried(ins[0].C, ins[0].lower, ins[0].upper)
    elif ins:
        sw = [math.sqrt(t.weight) for t in ins]
        own = _Carried(
            np.vstack([w * t.C for w, t in zip(sw, ins)]),
            np.concatenate([w * t.lower for w, t in zip(sw, ins)]),
            np.concatenate([w * t.upper for w, t in zip(sw, ins)]),
        )
    return A, b, own


def _movable(CZ: FloatArray, C: FloatArray | None, rel_tol: float = 1e-10) -> npt.NDArray[np.bool_]:
    """Rows of ``C Z`` the null-space step can still move (norm above ``rel_tol`` times that of ``C``'s row).

    A row the levels above have fixed (``C_i Z ~ 0``) cannot be changed by z; kept in a QP it is a
    near-zero row with a bound that rounding may put on the wrong side of zero, which some backends
    (proxsuite) report as infeasible. Its value stays what the levels above made it.
    """
    sq = np.einsum("ij,ij->i", CZ, CZ)
    ref = 1.0 if C is None else np.einsum("ij,ij->i", C, C)
    return sq > (rel_tol * rel_tol) * ref


def _kkt_optimal(problem: QPProblem, v: FloatArray, tol: float, kkt_tol: float = 1e-8) -> bool:
    """Whether ``v`` solves ``problem``: feasible within ``tol`` and the cost gradient in the cone of the active
    constraint normals (non-negative multipliers by NNLS, residual below ``kkt_tol`` relative).

    The level QPs of the hierarchy are degenerate when the levels above pin x to a vertex of the bounds (a
    CoM pushed out of reach drives joints to their velocity limits): their only feasible point is ``z = 0``,
    more bounds are active there than there are free directions, and daqp and proxsuite then report them
    infeasible. This check recognises that ``z = 0`` is optimal in that case (and any other).
    """
    grad = problem.H @ v + problem.g
    columns = []
    for C, lo, hi in ((problem.C, problem.l, problem.u), (None, problem.lb, problem.ub)):
        if lo is None:
            continue
        cv = v if C is None else C @ v
        if (cv < lo - tol).any() or (cv > hi + tol).any():
            return False
        at_lo, at_hi = cv - lo <= tol, hi - cv <= tol
        rows = np.eye(v.shape[0]) if C is None else C
        columns += [rows[at_lo].T, -rows[at_hi].T]
    B = np.hstack(columns) if columns else np.zeros((v.shape[0], 0))
    scale = kkt_tol * max(1.0, float(np.abs(grad).max()))
    if B.shape[1] == 0:
        return bool(np.abs(grad).max() <= scale)
    try:
        _, rnorm = nnls(B, grad, maxiter=50 * B.shape[1])
    except RuntimeError:  # pragma: no cover - iteration limit
        return False
    return bool(rnorm <= scale)


def _violation(rows: _Carried, x: FloatArray) -> FloatArray:
    cx = rows.C @ x
    return cx - np.clip(cx, rows.lo, rows.hi)


_NO_BLOCKS = np.zeros(0, dtype=np.intp)


@dataclass(slots=True)
class _ClosedFormPlan:
    """The shape of a hierarchy for ``HierarchicalSolver._solve_equalities``, kept while the same levels are
    solved again: tasks with rows (and their weights), rows per level, the leading levels whose rows fit in n
    (``n_prefix``, 0 when the path does not apply), and views spanning all rows when they are adjacent in
    memory (a controller's stack of task rows)."""

    tasks: list[tuple[EqualityTask, float]]
    counts: list[int]
    n_prefix: int
    r: int
    starts: npt.NDArray[np.intp]
    A: FloatArray | None
    b: FloatArray | None
    block_level: npt.NDArray[np.intp] = field(default_factory=lambda: _NO_BLOCKS)
    unit: bool = False  # every task of every level has weight 1 (then A, b span their rows)
    P: FloatArray | None = None
    b_P: FloatArray | None = None
    A_k: FloatArray | None = None
    c_k: FloatArray | None = None
    #: the per-task and per-level sums of squared residuals (`kernels.bounds_and_residuals`' outputs)
    sums: tuple[FloatArray, FloatArray] = ()

    def __post_init__(self) -> None:
        self.sums = (np.zeros(self.starts.shape[0]), np.zeros(len(self.counts)))

    @classmethod
    def of(cls, levels: tuple[Level, ...], n: int) -> _ClosedFormPlan:
        tasks: list[tuple[EqualityTask, float]] = []
        counts: list[int] = []
        block_level: list[int] = []
        none = cls([], [], 0, 0, np.zeros(0, dtype=np.intp), None, None)
        unit = True
        for k, level in enumerate(levels):
            count = 0
            for task in level.tasks:
                if type(task) is not EqualityTask:
                    return none
                unit = unit and task.weight == 1.0
                if task.weight > 0.0:
                    tasks.append((task, task.weight))
                    block_level.append(k)
                    count += task.A.shape[0]
            if count == 0:
                return none
            counts.append(count)
        if not tasks:
            return none
        r = n_prefix = 0
        for count in counts:
            if r + count > n:
                break
            r += count
            n_prefix += 1
        sizes = [t.A.shape[0] for t, _ in tasks]
        starts = np.cumsum([0] + sizes[:-1]).astype(np.intp)
        if all(w == 1.0 for _, w in tasks):
            A, b = _span([t.A for t, _ in tasks]), _span([t.b for t, _ in tasks])
            if A is not None and b is not None:
                k_end = r + counts[n_prefix] if n_prefix < len(counts) else r
                return cls(tasks, counts, n_prefix, r, starts, A, b, np.array(block_level, dtype=np.intp), unit,
                           A[:r], b[:r], A[r:k_end], b[r:k_end])
        return cls(tasks, counts, n_prefix, r, starts, None, None, np.array(block_level, dtype=np.intp))


def _span(arrays: list[FloatArray]) -> FloatArray | None:
    """A read-only view covering ``arrays`` (C-contiguous float64 blocks of equal trailing shape) when they lie
    one after the other in memory, else None."""
    first = arrays[0]
    if first.dtype != np.float64:
        return None
    end = first.__array_interface__["data"][0]
    for a in arrays:
        if a.dtype != np.float64 or not a.flags.c_contiguous or a.shape[1:] != first.shape[1:]:
            return None
        if a.__array_interface__["data"][0] != end:
            return None
        end += a.nbytes
    rows = sum(a.shape[0] for a in arrays)
    return np.lib.stride_tricks.as_strided(first, shape=(rows, *first.shape[1:]), writeable=False)


class _State:
    """The optimal set of the levels solved so far: point x, null-space basis Z (n, d), carried rows.

    Robustness against rounding: a backend must never report a level infeasible because the optimal set of
    the levels above is thinner than its tolerances (e.g. a point pinned by bounds). So x is clipped into the
    bounds after every level (a change of the order of the backend's primal tolerance), the carried rows
    are relaxed by ``tol`` (the feasibility tolerance), and a carried row the current point violates by
    rounding is only kept from getting worse. Together they make ``z = 0`` (stay where the levels above left
    x) feasible for every level QP after the first.
    """

    def __init__(self, n: int, lb: FloatArray, ub: FloatArray, tol: float):
        self.n = n
        self.lb, self.ub, self.tol = lb, ub, tol
        self.lb_tol, self.ub_tol = lb - tol, ub + tol
        self.bounded = np.flatnonzero(np.isfinite(lb) | np.isfinite(ub))
        self.x = np.zeros(n)
        self.Z: FloatArray | None = None  # None: identity
        self.d = n
        self.carried: _Carried | None = None

    def lift(self, z: FloatArray) -> FloatArray:
        """Step in x for a step z in the null-space coordinates."""
        return z if self.Z is None else self.Z @ z

    def feasible(self, point: FloatArray, own: _Carried | None) -> bool:
        """Bounds, carried rows and ``own`` rows hold at ``point`` within ``tol``."""
        if not ((point >= self.lb_tol).all() and (point <= self.ub_tol).all()):
            return False
        c = self.carried  # already relaxed by tol
        if c is not None:
            cx = c.C @ point
            if not ((cx >= c.lo).all() and (cx <= c.hi).all()):
                return False
        if own is not None:
            cx = own.C @ point
            if not ((cx >= own.lo - self.tol).all() and (cx <= own.hi + self.tol).all()):
                return False
        return True

    def carry(self, own: _Carried, slack: FloatArray | None) -> None:
        """Keep ``own`` rows for the levels below, shifted by their slack (None: 0) and relaxed by ``tol``."""
        if slack is None:
            lo, hi = own.lo - self.tol, own.hi + self.tol
        else:
            lo, hi = own.lo + (slack - self.tol), own.hi + (slack + self.tol)
        c = self.carried
        if c is None:
            self.carried = _Carried(own.C, lo, hi)
        else:
            self.carried = _Carried(np.vstack([c.C, own.C]), np.concatenate([c.lo, lo]), np.concatenate([c.hi, hi]))

    def problem(self, H: FloatArray, g: FloatArray, own: _Carried | None) -> QPProblem:
        """QP in (z, s) from the current point: bounds and carried rows on z, ``own`` rows with slacks s."""
        x, Z = self.x, self.Z
        m_own = 0 if own is None else own.C.shape[0]
        blocks, los, his = [], [], []
        box_lb = box_ub = None
        if Z is None:
            box_lb = np.concatenate([self.lb - x, np.full(m_own, -np.inf)])
            box_ub = np.concatenate([self.ub - x, np.full(m_own, np.inf)])
        elif self.bounded.size:
            Zb = Z if self.bounded.size == self.n else Z[self.bounded]
            keep = _movable(Zb, None)
            rows = self.bounded[keep]
            if rows.size:
                Zb = Zb[keep]
                blocks.append(np.hstack([Zb, np.zeros((Zb.shape[0], m_own))]) if m_own else Zb)
                los.append((self.lb - x)[rows])
                his.append((self.ub - x)[rows])
        for rows, slack in ((self.carried, False), (own, True)):
            if rows is None:
                continue
            C, lo, hi = rows.C, rows.lo, rows.hi
            CZ = C if Z is None else C @ Z
            if Z is not None and not slack:
                keep = _movable(CZ, C)
                if not keep.all():
                    C, lo, hi, CZ = C[keep], lo[keep], hi[keep], CZ[keep]
                    if not keep.any():
                        continue
            if m_own:
                CZ = np.hstack([CZ, -np.eye(m_own) if slack else np.zeros((CZ.shape[0], m_own))])
            cx = C @ x
            blocks.append(CZ)
            if slack:
                los.append(lo - cx)
                his.append(hi - cx)
            else:  # carried rows: the current point satisfies them up to rounding; never ask to fix that
                los.append(np.minimum(lo - cx, 0.0))
                his.append(np.maximum(hi - cx, 0.0))
        if not blocks:
            return QPProblem._trusted(H, g, lb=box_lb, ub=box_ub)
        return QPProblem._trusted(
            H, g, None, None, np.vstack(blocks), np.concatenate(los), np.concatenate(his), box_lb, box_ub
        )
