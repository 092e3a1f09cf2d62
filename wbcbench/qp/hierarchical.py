"""Hierarchical (lexicographic) least squares: strict priorities between levels, under hard bounds.

Problem (levels k = 1..K in priority order, variables x (n,), hard bounds ``lb <= x <= ub``)::

    level k:  min  sum_{i in k} w_i ||A_i x - b_i||^2 + sum_{j in k} w_j ||s_j||^2
              s.t. lower_j <= C_j x - s_j <= upper_j          (inequality tasks of level k, slacks s_j)
                   x optimal for every level above k
                   lb <= x <= ub

then ``min ||x||^2`` over the remaining optimal set (an implicit last level that makes x unique).

Method. The optimal set of a level is kept as (i) an orthonormal basis ``Z`` (n, d) of the directions the
levels above leave free, so that their equality rows keep their optimal values ``A_i x = A_i x*``, and
(ii) the inequality rows of the levels above relaxed by their optimal slacks,
``lower_j + s_j* <= C_j x <= upper_j + s_j*``. (The optimal ``(A_i x, s_j)`` of a level is unique, since the
cost is strictly convex in them, so this describes the optimal set exactly.) Level k works on ``x + Z z``:

- fast path: the least-squares step ``z`` of its equality rows in the null space (pivoted QR of
  ``(A_k Z)^T``, optional damping); if the new point satisfies the bounds, the carried inequality rows and
  the level's own inequality tasks (within ``feasibility_tol``), it is the level's optimum;
- otherwise a QP in ``(z, s)`` through a :class:`~wbcbench.qp.QPSolver` backend (daqp by default), with
  the bounds and carried rows as inequality rows in ``z``.

Then ``Z`` shrinks to the null space of ``A_k Z`` (rank-revealing, threshold ``rank_tol * ||A_k||_F``).
A level whose target is out of reach is met as well as possible in the least-squares sense and reported
``met = False``; lower levels still use whatever freedom is left.

Damping: ``damping = lambda > 0`` adds ``lambda^2 ||z||^2`` to every level's cost (a damped
pseudo-inverse on the fast path, the same Tikhonov term in the QP), trading exactness (bias about
``lambda^2 / sigma^2``) for bounded steps near singular configurations. With ``lambda = 0`` (default) each
level is solved exactly; a singular level Hessian in the QP path is handled by daqp's proximal iterations.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from wbcbench.qp._nullspace import least_squares_step, project
from wbcbench.qp.levels import EqualityTask, InequalityTask, Level, Task
from wbcbench.qp.problem import QPProblem
from wbcbench.qp.registry import make_solver, solver_names
from wbcbench.qp.result import QPStatus
from wbcbench.qp.solver import QPSolver

__all__ = ["HierarchicalSolver", "HierarchicalResult", "LevelReport", "LevelPath"]

FloatArray = npt.NDArray[np.float64]


class LevelPath(enum.Enum):
    """How a level was solved."""

    NULLSPACE = "nullspace"
    """Closed form in the null space of the levels above: no bound or inequality binds."""
    QP = "qp"
    """Constrained least squares through a QP backend (a bound or inequality binds)."""
    LOCKED = "locked"
    """No free direction left: the levels above fix x completely; the level is only evaluated."""
    FAILED = "failed"
    """The QP backend failed; the level was skipped (x unchanged, nothing fixed for the levels below)."""


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


@dataclass(frozen=True, slots=True)
class HierarchicalResult:
    """Solution of a hierarchical problem.

    Attributes:
        x: (n,) solution, always set (it is the best point found even when ``ok`` is False).
        levels: one :class:`LevelReport` per level, in priority order.
        ok: True when every level and the final min-norm step were solved (no :attr:`LevelPath.FAILED`).
        bound_violation: largest violation of ``lb <= x <= ub`` before the final clip (0 when none). x is
            always clipped into the bounds; a violation above ``feasibility_tol`` only happens after a
            failed level (``ok`` False).
        final_path: how the implicit min-norm level was solved.
    """

    x: FloatArray
    levels: tuple[LevelReport, ...]
    ok: bool
    bound_violation: float
    final_path: LevelPath

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
        feasibility_tol: absolute tolerance on bounds and inequality rows when accepting a fast-path step,
            and on the final clip into the bounds.
        met_tol: a level is reported met when its residual is at most this (weighted task units).
        fast_path: use the closed-form null-space step when nothing binds (False: always a QP; for tests and
            benchmarks).

    One instance keeps one QP workspace per level (warm-started from tick to tick); use one instance per
    hierarchy. Not thread-safe.
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
            raise ValueError(f"HierarchicalSolver: n must be a positive integer, got {n!r}")
        if solver not in solver_names():
            raise ValueError(f"HierarchicalSolver: unknown QP solver {solver!r}; valid: {', '.join(solver_names())}")
        for key, value in (("damping", damping), ("rank_tol", rank_tol), ("feasibility_tol", feasibility_tol),
                           ("met_tol", met_tol)):
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"HierarchicalSolver: {key} must be finite and >= 0, got {value!r}")
        self.n = int(n)
        self.solver_name = solver
        self.solver_options = dict(solver_options or {})
        make_solver(solver, **self.solver_options)  # fail now on bad options
        self.damping = float(damping)
        self.rank_tol = float(rank_tol)
        self.feasibility_tol = float(feasibility_tol)
        self.met_tol = float(met_tol)
        self.fast_path = bool(fast_path)
        self._solvers: dict[int | str, QPSolver] = {}

    # ------------------------------------------------------------------ input

    def _levels(self, levels: Sequence[Level | Sequence[Task] | Task]) -> tuple[Level, ...]:
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
                    raise ValueError(f"HierarchicalSolver: level {k}: {exc}") from None
        seen: dict[str, int] = {}
        for k, level in enumerate(out):
            for task in level.tasks:
                if task.name in seen:
                    raise ValueError(
                        f"HierarchicalSolver: task name '{task.name}' appears twice (levels {seen[task.name]} and {k})"
                    )
                seen[task.name] = k
                if task.n_cols != self.n:
                    raise ValueError(
                        f"HierarchicalSolver: level {k} ('{level.name}'), task '{task.name}': "
                        f"{task.n_cols} columns, expected n = {self.n}"
                    )
        return tuple(out)

    def _bounds(self, lower: Any, upper: Any) -> tuple[FloatArray, FloatArray]:
        bounds = []
        for value, fill, side in ((lower, -np.inf, "lower"), (upper, np.inf, "upper")):
            if value is None:
                bounds.append(np.full(self.n, fill))
                continue
            array = np.asarray(value, dtype=np.float64)
            if array.shape != (self.n,):
                raise ValueError(f"HierarchicalSolver: {side} bounds must have shape ({self.n},), got {array.shape}")
            if np.isnan(array).any():
                raise ValueError(f"HierarchicalSolver: {side} bounds contain NaN")
            bounds.append(array)
        lb, ub = bounds
        bad = np.flatnonzero(lb > ub)
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"HierarchicalSolver: lower bound above upper bound for variable {i} ({lb[i]} > {ub[i]})")
        return lb, ub

    def _solver(self, key: int | str) -> QPSolver:
        solver = self._solvers.get(key)
        if solver is None:
            solver = self._solvers[key] = make_solver(self.solver_name, **self.solver_options)
        return solver

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

    def _level(self, k: int, level: Level, st: _State) -> tuple[LevelPath, int, int, QPStatus | None, int]:
        """Solve one level in place on ``st``; returns (path, rank, freedom, qp status, qp iterations)."""
        eqs = [t for t in level.tasks if isinstance(t, EqualityTask) and t.weight > 0.0]
        ins = [t for t in level.tasks if isinstance(t, InequalityTask) and t.weight > 0.0]
        A = r = None
        if eqs:
            A = np.vstack([t.A if t.weight == 1.0 else math.sqrt(t.weight) * t.A for t in eqs])
            b = np.concatenate([t.b if t.weight == 1.0 else math.sqrt(t.weight) * t.b for t in eqs])
            r = b - A @ st.x
        own = None
        if ins:
            sw = [math.sqrt(t.weight) for t in ins]
            own = _Carried(
                np.vstack([w * t.C for w, t in zip(sw, ins)]),
                np.concatenate([w * t.lower for w, t in zip(sw, ins)]),
                np.concatenate([w * t.upper for w, t in zip(sw, ins)]),
            )
        freedom = st.d
        if st.d == 0 or (A is None and own is None):
            if own is not None:
                st.carry(own, _violation(own, st.x))
            return (LevelPath.LOCKED if st.d == 0 else LevelPath.NULLSPACE), 0, freedom, None, 0

        proj = None
        candidate = st.x
        if A is not None:
            M = A if st.Z is None else A @ st.Z
            proj = project(M, st.Z, st.n, self.rank_tol * _frobenius(A))
            if proj.rank:
                y = least_squares_step(proj, r, self.damping)
                candidate = st.x + proj.ZQ[:, : proj.rank] @ y

        status, iterations = None, 0
        m_own = 0 if own is None else own.C.shape[0]
        if self.fast_path and st.feasible(candidate, own):
            path, slack = LevelPath.NULLSPACE, np.zeros(m_own)
            st.x = candidate
        else:
            d = st.d
            H = np.zeros((d + m_own, d + m_own))
            g = np.zeros(d + m_own)
            if A is not None:
                np.matmul(M.T, M, out=H[:d, :d])
                g[:d] = -(M.T @ r)
            diag = H.reshape(-1)[:: d + m_own + 1]
            diag[:d] += self.damping**2
            diag[d:] = 1.0
            result = self._solver(k).solve(st.problem(H, g, own))
            status, iterations = result.status, result.iterations
            if result.x is None:
                return LevelPath.FAILED, 0, freedom, status, iterations
            path, slack = LevelPath.QP, result.x[d:]
            st.x = st.x + st.lift(result.x[:d])

        # What the levels below must keep: the equality rows, and the inequality rows this level could not
        # satisfy (nonzero slack), at their values; the satisfied inequality rows as inequalities.
        rank = 0 if proj is None else proj.rank
        if own is not None:
            violated = np.abs(slack) > st.tol
            if violated.any():
                fixed = own.C[violated] if A is None else np.vstack([A, own.C[violated]])
                M = fixed if st.Z is None else fixed @ st.Z
                proj = project(M, st.Z, st.n, self.rank_tol * _frobenius(fixed))
                rank = proj.rank
                kept = ~violated
                own = _Carried(own.C[kept], own.lo[kept], own.hi[kept]) if kept.any() else None
                slack = slack[kept]
            if own is not None:
                st.carry(own, slack)
        if proj is not None and proj.rank:
            st.Z = proj.ZQ[:, proj.rank :]
            st.d = st.Z.shape[1]
        return path, rank, freedom, status, iterations

    def _min_norm(self, st: _State) -> LevelPath:
        """Implicit last level: ``min ||x||^2`` over the optimal set of all levels."""
        if st.d == 0:
            return LevelPath.LOCKED
        Ztx = st.x if st.Z is None else st.Z.T @ st.x
        candidate = st.x - st.lift(Ztx)
        if self.fast_path and st.feasible(candidate, None):
            st.x = candidate
            return LevelPath.NULLSPACE
        result = self._solver("final").solve(st.problem(np.eye(st.d), np.array(Ztx), None))
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
            k, level.name, residual, task_residuals, residual <= self.met_tol, rank, freedom, path, status, iterations
        )


def _frobenius(A: FloatArray) -> float:
    return max(math.sqrt(float(np.einsum("ij,ij->", A, A))), np.finfo(float).tiny)


def _movable(CZ: FloatArray, C: FloatArray | None, rel_tol: float = 1e-10) -> npt.NDArray[np.bool_]:
    """Rows of ``C Z`` the null-space step can still move (norm above ``rel_tol`` times that of ``C``'s row).

    A row the levels above have fixed (``C_i Z ~ 0``) cannot be changed by z; kept in a QP it is a
    near-zero row with a bound that rounding may put on the wrong side of zero, which some backends
    (proxsuite) report as infeasible. Its value stays what the levels above made it.
    """
    sq = np.einsum("ij,ij->i", CZ, CZ)
    ref = 1.0 if C is None else np.einsum("ij,ij->i", C, C)
    return sq > (rel_tol * rel_tol) * ref


def _violation(rows: _Carried, x: FloatArray) -> FloatArray:
    cx = rows.C @ x
    return cx - np.clip(cx, rows.lo, rows.hi)


class _State:
    """The optimal set of the levels solved so far: point x, null-space basis Z (n, d), carried rows.

    The carried rows and, in the QPs, the bounds are relaxed by ``tol`` (the feasibility tolerance): rounding
    can leave the optimal set of the levels above thinner than the backends' tolerances (a point pinned by
    bounds), and a backend must not report such a level infeasible. The returned x is clipped into the bounds.
    """

    def __init__(self, n: int, lb: FloatArray, ub: FloatArray, tol: float):
        self.n = n
        self.lb, self.ub, self.tol = lb, ub, tol
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
        tol = self.tol
        if not ((point >= self.lb - tol).all() and (point <= self.ub + tol).all()):
            return False
        for rows in (self.carried, own):
            if rows is not None:
                cx = rows.C @ point
                if not ((cx >= rows.lo - tol).all() and (cx <= rows.hi + tol).all()):
                    return False
        return True

    def carry(self, own: _Carried, slack: FloatArray) -> None:
        """Keep ``own`` rows for the levels below, shifted by their slack and relaxed by ``tol``."""
        lo, hi = own.lo + (slack - self.tol), own.hi + (slack + self.tol)
        c = self.carried
        if c is None:
            self.carried = _Carried(own.C, lo, hi)
        else:
            self.carried = _Carried(np.vstack([c.C, own.C]), np.concatenate([c.lo, lo]), np.concatenate([c.hi, hi]))

    def problem(self, H: FloatArray, g: FloatArray, own: _Carried | None) -> QPProblem:
        """QP in (z, s) from the current point: bounds and carried rows on z, ``own`` rows with slacks s."""
        x, Z, d, tol = self.x, self.Z, self.d, self.tol
        m_own = 0 if own is None else own.C.shape[0]
        blocks, los, his = [], [], []
        box_lb = box_ub = None
        if Z is None:
            box_lb = np.concatenate([self.lb - x - tol, np.full(m_own, -np.inf)])
            box_ub = np.concatenate([self.ub - x + tol, np.full(m_own, np.inf)])
        elif self.bounded.size:
            Zb = Z if self.bounded.size == self.n else Z[self.bounded]
            keep = _movable(Zb, None)
            rows = self.bounded[keep]
            if rows.size:
                Zb = Zb[keep]
                blocks.append(np.hstack([Zb, np.zeros((Zb.shape[0], m_own))]) if m_own else Zb)
                los.append((self.lb - x)[rows] - tol)
                his.append((self.ub - x)[rows] + tol)
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
            los.append(lo - cx)
            his.append(hi - cx)
        if not blocks:
            return QPProblem._trusted(H, g, lb=box_lb, ub=box_ub)
        return QPProblem._trusted(
            H, g, None, None, np.vstack(blocks), np.concatenate(los), np.concatenate(his), box_lb, box_ub
        )
