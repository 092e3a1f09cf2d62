"""Test-only references: exact QPs built from their KKT conditions, random hierarchies, and a slow HQP cascade.

Nothing here is fast or clever on purpose: the cascade solves one full-space QP per level with the levels
above written out as explicit constraints, so that it shares no code path with
:class:`wbcbench.qp.HierarchicalSolver` (no null-space basis, no fast path, no pivoted QR).
"""

from __future__ import annotations

from dataclasses import dataclass

import daqp
import numpy as np
from proxsuite import proxqp

from wbcbench.qp import EqualityTask, InequalityTask, Level, QPProblem


# ---------------------------------------------------------------------------------------------------- plain QPs


@dataclass(frozen=True)
class KnownQP:
    """A QP whose unique solution ``x_star`` is known by construction (KKT conditions)."""

    problem: QPProblem
    x_star: np.ndarray
    n_active: int


def known_qp(rng: np.random.Generator, n: int, m_eq: int, m_in: int, box: bool) -> KnownQP:
    """Random strictly convex QP with prescribed solution, active set and multipliers.

    Stationarity ``H x* + g + A_eq^T y + C^T lam + mu = 0`` with ``lam_i > 0`` on rows active at ``u``,
    ``< 0`` on rows active at ``l``, 0 on inactive rows (kept at least 0.1 away from their bounds); the same
    for the box multipliers ``mu``. Convexity makes these conditions sufficient, H > 0 makes x* unique.
    """
    J = rng.standard_normal((n + 3, n))
    H = J.T @ J + 0.1 * np.eye(n)
    x_star = rng.standard_normal(n)
    grad = H @ x_star
    budget = max(n - m_eq - 1, 0)  # active inequality rows + active bounds stay below n - m_eq
    A_eq = b_eq = C = lo = up = lb = ub = None
    if m_eq:
        A_eq = rng.standard_normal((m_eq, n))
        b_eq = A_eq @ x_star
        grad = grad + A_eq.T @ rng.standard_normal(m_eq)
    n_active = 0
    if m_in:
        C = rng.standard_normal((m_in, n))
        cx = C @ x_star
        lo = cx - rng.uniform(0.1, 2.0, m_in)
        up = cx + rng.uniform(0.1, 2.0, m_in)
        lo[rng.random(m_in) < 0.2] = -np.inf
        up[rng.random(m_in) < 0.2] = np.inf
        lam = np.zeros(m_in)
        for i in rng.permutation(m_in)[: min(budget, m_in // 2 + 1)]:
            if rng.random() < 0.5:
                up[i], lam[i] = cx[i], rng.uniform(0.1, 2.0)
            else:
                lo[i], lam[i] = cx[i], -rng.uniform(0.1, 2.0)
            n_active += 1
        grad = grad + C.T @ lam
    if box:
        lb = x_star - rng.uniform(0.1, 2.0, n)
        ub = x_star + rng.uniform(0.1, 2.0, n)
        mu = np.zeros(n)
        for i in rng.permutation(n)[: max(min(budget - n_active, n // 3), 0)]:
            if rng.random() < 0.5:
                ub[i], mu[i] = x_star[i], rng.uniform(0.1, 2.0)
            else:
                lb[i], mu[i] = x_star[i], -rng.uniform(0.1, 2.0)
            n_active += 1
        grad = grad + mu
    g = -grad
    return KnownQP(QPProblem(H, g, A_eq, b_eq, C, lo, up, lb, ub), x_star, n_active)


# ---------------------------------------------------------------------------------------------------- hierarchies


def random_hierarchy(
    rng: np.random.Generator, n: int, n_levels: int, *, bound_scale: float = 1.0, with_inequalities: bool = True
) -> tuple[list[Level], np.ndarray, np.ndarray]:
    """Random levels (equality tasks, sometimes rank-deficient; sometimes inequality tasks) and box bounds.

    ``bound_scale`` sets how tight the bounds are compared with typical task solutions (small: they bind).
    """
    levels = []
    for k in range(n_levels):
        tasks = []
        for t in range(int(rng.integers(1, 3))):
            name = f"l{k}t{t}"
            if with_inequalities and rng.random() < 0.3:
                m = int(rng.integers(1, 4))
                C = rng.standard_normal((m, n))
                center = rng.standard_normal(m)
                half = rng.uniform(0.0, 0.5, m)
                tasks.append(InequalityTask(name, C, center - half, center + half, weight=float(rng.uniform(0.5, 2))))
            else:
                m = int(rng.integers(1, n + 1))
                A = rng.standard_normal((m, n))
                if m >= 2 and rng.random() < 0.3:
                    A[-1] = A[0] * rng.uniform(0.5, 2.0)  # rank-deficient rows
                b = 2.0 * rng.standard_normal(m)
                tasks.append(EqualityTask(name, A, b, weight=float(rng.uniform(0.5, 2))))
        levels.append(Level(tuple(tasks), name=f"level{k}"))
    center = 0.3 * rng.standard_normal(n)
    lb = center - bound_scale * rng.uniform(0.2, 1.5, n)
    ub = center + bound_scale * rng.uniform(0.2, 1.5, n)
    free = rng.random(n) < 0.15
    lb[free], ub[free] = -np.inf, np.inf
    return levels, lb, ub


def _row_basis(A: np.ndarray, rank_tol: float = 1e-9) -> np.ndarray:
    """Orthonormal basis (r, n) of the row space of A, by SVD."""
    if A.shape[0] == 0:
        return A
    _, s, Vt = np.linalg.svd(A, full_matrices=False)
    r = int(np.sum(s > rank_tol * max(s[0], 1e-300)))
    return Vt[:r]


def _solve_reference_qp(H, g, A, lo, hi, n_eq, lb, ub) -> np.ndarray:
    """Raw solver calls: the first n_eq rows of A are equalities; lb/ub are simple bounds on the first variables.

    daqp calls some degenerate or badly conditioned problems of this explicit-constraint form infeasible;
    the reference then retries with a looser primal tolerance, with the equality rows and the bounds widened
    by 1e-8, with forced proximal iterations, and last with proxsuite (1e-11).
    """
    nb = len(lb)
    for primal_tol, widen, eps_prox in ((1e-9, 0.0, -1e-6), (1e-7, 0.0, -1e-6), (1e-9, 1e-8, -1e-6), (1e-9, 0.0, 1e-4)):
        sense = np.zeros(nb + A.shape[0], dtype=np.intc)
        if not widen:
            sense[nb : nb + n_eq] = 5
        x, _, flag, _ = daqp.solve(
            H, g, np.ascontiguousarray(A), np.concatenate([ub + widen, hi + widen]),
            np.concatenate([lb - widen, lo - widen]), sense,
            primal_tol=primal_tol, dual_tol=1e-10, iter_limit=100_000, eps_prox=eps_prox,
        )
        if flag >= 1:
            return x
    n = H.shape[0]
    box_rows = np.eye(n)[:nb]
    C = np.vstack([box_rows, A[n_eq:]])
    qp = proxqp.dense.QP(n, n_eq, C.shape[0])
    qp.settings.eps_abs, qp.settings.eps_rel, qp.settings.max_iter = 1e-11, 0.0, 100_000
    qp.settings.check_duality_gap = True
    qp.init(H, g, A[:n_eq], lo[:n_eq], C, np.concatenate([lb, lo[n_eq:]]), np.concatenate([ub, hi[n_eq:]]))
    qp.solve()
    if qp.results.info.status == proxqp.PROXQP_SOLVED:
        return np.array(qp.results.x)
    raise RuntimeError(f"reference QP failed (daqp flag {flag}, proxsuite {qp.results.info.status})")


def reference_hierarchy(
    levels: list[Level],
    lb: np.ndarray,
    ub: np.ndarray,
    damping: float = 0.0,
    margin: float = 1e-9,
    slack_as_equality: float = 1e-6,
) -> np.ndarray:
    """Slow cascade: one full-space QP per level, every level above written out as explicit constraints.

    Level k, variables (x, s): ``min ||A x - b||^2 + ||s||^2 + damping^2 ||x - x_{k-1}||^2`` s.t. the
    equality rows of the levels above, and their inequality rows left violated, kept at their values at
    ``x_{k-1}`` (through an orthonormal basis of their row space, so no redundant rows), their satisfied
    inequality rows kept satisfied (relaxed by ``margin``, as the solver under test does with its
    ``feasibility_tol``), own inequality rows with slacks, and the box on x. Then ``min ||x||^2`` on the
    final optimal set. A row counts as violated when its slack exceeds ``slack_as_equality`` (the solver's
    threshold; without damping the two descriptions of the optimal set coincide, with damping they differ
    for slacks below it).
    """
    n = lb.shape[0]
    x = np.zeros(n)
    fixed = np.zeros((0, n))
    carried_C, carried_lo, carried_hi = np.zeros((0, n)), np.zeros(0), np.zeros(0)
    for level in levels:
        eqs = [t for t in level.tasks if isinstance(t, EqualityTask) and t.weight > 0]
        ins = [t for t in level.tasks if isinstance(t, InequalityTask) and t.weight > 0]
        A = np.vstack([np.sqrt(t.weight) * t.A for t in eqs]) if eqs else np.zeros((0, n))
        b = np.concatenate([np.sqrt(t.weight) * t.b for t in eqs]) if eqs else np.zeros(0)
        C = np.vstack([np.sqrt(t.weight) * t.C for t in ins]) if ins else np.zeros((0, n))
        lo = np.concatenate([np.sqrt(t.weight) * t.lower for t in ins]) if ins else np.zeros(0)
        hi = np.concatenate([np.sqrt(t.weight) * t.upper for t in ins]) if ins else np.zeros(0)
        m_s = C.shape[0]
        E = _row_basis(fixed)
        H = np.zeros((n + m_s, n + m_s))
        H[:n, :n] = A.T @ A + damping**2 * np.eye(n)
        H[n:, n:] = np.eye(m_s)
        g = np.concatenate([-A.T @ b - damping**2 * x, np.zeros(m_s)])
        rows = np.vstack([
            np.hstack([E, np.zeros((E.shape[0], m_s))]),
            np.hstack([carried_C, np.zeros((carried_C.shape[0], m_s))]),
            np.hstack([C, -np.eye(m_s)]),
        ])
        row_lo = np.concatenate([E @ x, carried_lo, lo])
        row_hi = np.concatenate([E @ x, carried_hi, hi])
        sol = _solve_reference_qp(
            H, g, rows, row_lo, row_hi, E.shape[0],
            np.concatenate([lb, np.full(m_s, -np.inf)]), np.concatenate([ub, np.full(m_s, np.inf)]),
        )
        x, s = np.clip(sol[:n], lb, ub), sol[n:]  # as the solver under test: back into the box after each level
        violated = np.abs(s) > slack_as_equality  # rows left violated keep their value, like equality rows
        fixed = np.vstack([fixed, A, C[violated]])
        kept = ~violated
        carried_C = np.vstack([carried_C, C[kept]])
        carried_lo = np.concatenate([carried_lo, lo[kept] + s[kept] - margin])
        carried_hi = np.concatenate([carried_hi, hi[kept] + s[kept] + margin])
    E = _row_basis(fixed)
    rows = np.vstack([E, carried_C])
    return _solve_reference_qp(
        np.eye(n), np.zeros(n), rows, np.concatenate([E @ x, carried_lo]), np.concatenate([E @ x, carried_hi]),
        E.shape[0], lb, ub,
    )


def level_residuals(levels: list[Level], x: np.ndarray) -> list[float]:
    """Weighted residual of each level at x (same definition as LevelReport.residual)."""
    out = []
    for level in levels:
        total = 0.0
        for t in level.tasks:
            e = t.residual(x) if isinstance(t, EqualityTask) else t.violation(x)
            total += t.weight * float(e @ e)
        out.append(float(np.sqrt(total)))
    return out
