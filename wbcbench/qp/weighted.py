"""Weighted QP builder: cost terms ``w ||A x - b||^2`` plus constraints, assembled without per-tick allocation."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from wbcbench.qp.problem import QPProblem
from wbcbench.qp.registry import make_solver
from wbcbench.qp.result import QPResult
from wbcbench.qp.solver import QPSolver

__all__ = ["WeightedQP"]

FloatArray = npt.NDArray[np.float64]


@dataclass(slots=True)
class _Slot:
    """Rows ``[start, stop)`` of a stacked buffer, holding one term or constraint over columns ``cols``."""

    name: str
    start: int
    stop: int
    cols: slice
    block: FloatArray  # view buffer[start:stop, cols]
    vectors: tuple[FloatArray, ...]  # views of the row vectors (b, or l and u) on [start:stop]


class _Stack:
    """A growable row-stacked matrix (rows x n) with companion row vectors, reused tick after tick.

    Slots are matched by call order: when the i-th add of a tick has the same (rows, cols) as the i-th add
    of the previous tick, its views are reused and the zero padding outside ``cols`` is still in place.
    """

    def __init__(self, n: int, n_vectors: int, capacity: int = 64):
        self.n = n
        self.n_vectors = n_vectors
        self._alloc(capacity)
        self.slots: list[_Slot] = []
        self.count = 0  # slots used this tick
        self.rows = 0  # rows used this tick
        self.col_start = n  # column span of the slots used this tick
        self.col_stop = 0

    def _alloc(self, capacity: int) -> None:
        self.matrix = np.zeros((capacity, self.n))
        self.vectors = [np.zeros(capacity) for _ in range(self.n_vectors)]

    def clear(self) -> None:
        self.count = 0
        self.rows = 0
        self.col_start = self.n
        self.col_stop = 0

    def next_slot(self, name: str, m: int, cols: slice) -> _Slot:
        if cols.start < self.col_start:
            self.col_start = cols.start
        if cols.stop > self.col_stop:
            self.col_stop = cols.stop
        i = self.count
        if i < len(self.slots):
            slot = self.slots[i]
            if slot.stop - slot.start == m and slot.cols == cols and slot.start == self.rows:
                slot.name = name
                self.count += 1
                self.rows = slot.stop
                return slot
            del self.slots[i:]  # the layout changed from here on
        start, stop = self.rows, self.rows + m
        if stop > self.matrix.shape[0]:
            old_matrix, old_vectors = self.matrix, self.vectors
            self._alloc(max(2 * self.matrix.shape[0], stop))
            self.matrix[:start] = old_matrix[:start]
            for new, old in zip(self.vectors, old_vectors):
                new[:start] = old[:start]
            # Earlier slots point into the old buffer: rebind them (their contents were copied).
            for slot in self.slots:
                slot.block = self.matrix[slot.start : slot.stop, slot.cols]
                slot.vectors = tuple(v[slot.start : slot.stop] for v in self.vectors)
        self.matrix[start:stop] = 0.0
        slot = _Slot(
            name, start, stop, cols, self.matrix[start:stop, cols], tuple(v[start:stop] for v in self.vectors)
        )
        self.slots.append(slot)
        self.count += 1
        self.rows = stop
        return slot

    def used(self) -> tuple[FloatArray, list[FloatArray]]:
        r = self.rows
        return self.matrix[:r], [v[:r] for v in self.vectors]

    def slot_at_row(self, row: int) -> _Slot:
        for slot in self.slots[: self.count]:
            if slot.start <= row < slot.stop:
                return slot
        raise IndexError(row)  # pragma: no cover - rows always belong to a slot


class WeightedQP:
    """Builder for ``min 1/2 sum_i w_i ||A_i x - b_i||^2_{W_i} + 1/2 eps ||x||^2`` under linear constraints.

    The cost terms become, with ``J_i = sqrt(w_i W_i) A_i`` and ``c_i = sqrt(w_i W_i) b_i`` stacked into one
    preallocated matrix ``J`` (rows x n) and vector ``c``::

        H = J^T J + D + eps I      (n, n), D the diagonal terms of add_diagonal_cost
        g = -J^T c - D t           (n,)

    which has the minimiser of ``sum_i w_i ||A_i x - b_i||^2 + eps ||x||^2`` (the 1/2 only scales the
    objective). ``W_i`` is an optional diagonal of per-row weights. Constraints are stacked the same way.
    ``J^T J`` is computed on the column span the terms use (e.g. only the 38 acceleration columns of
    ``[dv; f]``), so diagonal terms on other columns (force regularisation) cost no matrix product.

    Use per control tick::

        qp.clear()
        qp.add_cost(A_com, b_com, 1e3, name="com")        # A: (m, n) or (m, len(cols)) with cols=
        qp.add_diagonal_cost(0.1, q_ref, cols=joints, name="posture")
        qp.add_equality(A_dyn, b_dyn, name="dynamics")
        qp.add_inequality(C_fric, upper=u_fric, name="friction")
        qp.set_bounds(lb, ub)
        result = qp.solve()                                 # or problem = qp.build(); solver.solve(problem)

    Buffers grow on demand and are then reused: when each tick adds the same terms in the same order with
    the same shapes, assembly allocates no matrix (only a few small views). Terms may act on a contiguous
    column range (``cols=slice(a, b)``); the other columns of their rows stay zero.

    Args:
        n: number of variables.
        regularization: Tikhonov weight ``eps`` >= 0 (cost units per variable unit squared); it keeps ``H``
            positive definite when the terms do not cover every direction and biases the solution by about
            ``eps / sigma^2`` relative, sigma the smallest singular value of the stacked weighted rows.
        solver: a backend instance or registry name, used by :meth:`solve`.
        check: let :meth:`build` check the assembled data for non-finite entries and disordered bounds (about
            a quarter of the assembly time); shapes and weights are always checked when terms are added.

    Raises:
        ValueError: bad sizes or settings; the message names the term.
    """

    def __init__(
        self, n: int, *, regularization: float = 1e-6, solver: QPSolver | str = "daqp", check: bool = True
    ):
        if int(n) != n or n < 1:
            raise ValueError(f"WeightedQP: n must be a positive integer, got {n!r}")
        if not (math.isfinite(regularization) and regularization >= 0.0):
            raise ValueError(f"WeightedQP: regularization must be finite and >= 0, got {regularization!r}")
        self.n = int(n)
        self.regularization = float(regularization)
        self.check = bool(check)
        self.solver: QPSolver = make_solver(solver) if isinstance(solver, str) else solver
        self._all = slice(0, self.n)
        self._costs = _Stack(self.n, 1)  # vector: -c (negated targets, so that g = J^T (-c))
        self._eqs = _Stack(self.n, 1)
        self._ins = _Stack(self.n, 2)
        self._H = np.zeros((self.n, self.n))
        self._H_diag = self._H.reshape(-1)[:: self.n + 1]
        self._g = np.zeros(self.n)
        self._diag_w = np.zeros(self.n)  # diagonal cost weights D
        self._diag_wt = np.zeros(self.n)  # D t
        self._diag_used = False
        self._diag_names: list[tuple[str, slice, Any, Any]] = []
        self._lb = np.full(self.n, -np.inf)
        self._ub = np.full(self.n, np.inf)
        self._has_bounds = False
        self._problem: QPProblem | None = None

    # ------------------------------------------------------------------ per-tick input

    def clear(self) -> None:
        """Forget this tick's terms, constraints and bounds (buffers are kept)."""
        self._costs.clear()
        self._eqs.clear()
        self._ins.clear()
        if self._diag_used:
            self._diag_w.fill(0.0)
            self._diag_wt.fill(0.0)
            self._diag_used = False
            self._diag_names.clear()
        self._has_bounds = False
        self._problem = None

    def _cols(self, cols: slice | None, name: str) -> tuple[slice, int]:
        if cols is None:
            return self._all, self.n
        start, stop, step = cols.indices(self.n)
        if step != 1 or stop <= start:
            raise ValueError(f"WeightedQP: '{name}': cols must be a non-empty contiguous slice, got {cols}")
        return slice(start, stop), stop - start

    def _matrix(self, A: Any, width: int, name: str, what: str) -> npt.NDArray[np.float64]:
        A = np.asarray(A, dtype=np.float64)
        if A.ndim != 2 or A.shape[1] != width:
            raise ValueError(f"WeightedQP: {what} '{name}': matrix must have shape (m, {width}), got {A.shape}")
        return A

    def _vector(self, b: Any, m: int, name: str, what: str, key: str) -> npt.NDArray[np.float64]:
        b = np.asarray(b, dtype=np.float64)
        if b.shape != (m,):
            raise ValueError(f"WeightedQP: {what} '{name}': {key} must have shape ({m},), got {b.shape}")
        return b

    def add_cost(
        self,
        A: Any,
        b: Any,
        weight: float = 1.0,
        *,
        row_weights: Any = None,
        cols: slice | None = None,
        name: str = "",
    ) -> None:
        """Add ``weight * ||diag(row_weights)^(1/2) (A x[cols] - b)||^2`` to the cost.

        Args:
            A: (m, n) task rows, or (m, k) when ``cols`` selects k columns.
            b: (m,) targets, in the task's units.
            weight: scalar >= 0 (cost units per task unit squared). Zero removes the term's effect.
            row_weights: optional (m,) per-row weights >= 0, multiplied with ``weight``.
            cols: contiguous column range the rows act on; None for all n.
            name: label used in error messages and :meth:`term_costs`.
        """
        name = name or f"cost[{self._costs.count}]"
        sl, width = self._cols(cols, name)
        A = self._matrix(A, width, name, "cost")
        m = A.shape[0]
        b = self._vector(b, m, name, "cost", "b")
        if not (weight >= 0.0 and math.isfinite(weight)):
            raise ValueError(f"WeightedQP: cost '{name}': weight must be finite and >= 0, got {weight!r}")
        slot = self._costs.next_slot(name, m, sl)
        if weight == 0.0:  # no effect; still refuse garbage (0 * inf would be nan in the stack)
            if not (np.isfinite(A).all() and np.isfinite(b).all()):
                raise ValueError(f"WeightedQP: cost '{name}' has non-finite entries")
            slot.block.fill(0.0)
            slot.vectors[0].fill(0.0)
            return
        if row_weights is None:
            s = math.sqrt(weight)
            np.multiply(A, s, out=slot.block)
            np.multiply(b, -s, out=slot.vectors[0])
            return
        rw = self._vector(row_weights, m, name, "cost", "row_weights")
        if not (rw >= 0.0).all() or not np.isfinite(rw).all():
            raise ValueError(f"WeightedQP: cost '{name}': row_weights must be finite and >= 0")
        s_rows = np.sqrt(rw * weight)
        np.multiply(A, s_rows[:, None], out=slot.block)
        np.multiply(b, -s_rows, out=slot.vectors[0])

    def add_diagonal_cost(self, weight: Any, target: Any = None, *, cols: slice | None = None, name: str = "") -> None:
        """Add ``sum_j w_j (x_j - t_j)^2`` over ``x[cols]``: a posture or regularisation term without rows.

        Same as ``add_cost(I, target, ...)`` with per-row weights, but it only touches the diagonal of ``H``.

        Args:
            weight: scalar or (k,) weights >= 0, k the number of selected columns.
            target: (k,) targets ``t`` in variable units, or None for 0.
            cols: contiguous column range; None for all n.
            name: label used in error messages and :meth:`term_costs`.
        """
        name = name or f"diagonal[{len(self._diag_names)}]"
        sl, width = self._cols(cols, name)
        if isinstance(weight, (int, float)):
            if not (weight >= 0.0 and math.isfinite(weight)):
                raise ValueError(f"WeightedQP: diagonal cost '{name}': weight must be finite and >= 0, got {weight!r}")
            w: Any = float(weight)
        else:
            w = np.asarray(weight, dtype=np.float64)
            if w.shape not in ((), (width,)) or not np.isfinite(w).all() or not (w >= 0.0).all():
                raise ValueError(
                    f"WeightedQP: diagonal cost '{name}': weight must be finite >= 0, scalar or ({width},)"
                )
        self._diag_w[sl] += w
        if target is not None:
            t = self._vector(target, width, name, "diagonal cost", "target")
            self._diag_wt[sl] += w * t
        self._diag_used = True
        self._diag_names.append((name, sl, w, target))

    def add_equality(self, A: Any, b: Any, *, cols: slice | None = None, name: str = "") -> None:
        """Add hard rows ``A x[cols] = b``: A (m, n) or (m, k) with ``cols``, b (m,)."""
        name = name or f"equality[{self._eqs.count}]"
        sl, width = self._cols(cols, name)
        A = self._matrix(A, width, name, "equality")
        m = A.shape[0]
        b = self._vector(b, m, name, "equality", "b")
        slot = self._eqs.next_slot(name, m, sl)
        np.copyto(slot.block, A)
        np.copyto(slot.vectors[0], b)

    def add_inequality(
        self,
        C: Any,
        lower: Any = None,
        upper: Any = None,
        *,
        cols: slice | None = None,
        name: str = "",
    ) -> None:
        """Add hard rows ``lower <= C x[cols] <= upper``: C (m, n) or (m, k) with ``cols``.

        ``lower`` / ``upper``: (m,) bounds (or scalars), ``-inf`` / ``+inf`` allowed; None means no bound on
        that side.
        """
        name = name or f"inequality[{self._ins.count}]"
        sl, width = self._cols(cols, name)
        C = self._matrix(C, width, name, "inequality")
        m = C.shape[0]
        if lower is None and upper is None:
            raise ValueError(f"WeightedQP: inequality '{name}': give lower, upper or both")
        for value, side in ((lower, "lower"), (upper, "upper")):
            if value is not None and np.shape(value) not in ((m,), ()):
                raise ValueError(
                    f"WeightedQP: inequality '{name}': {side} must have shape ({m},), got {np.shape(value)}"
                )
        slot = self._ins.next_slot(name, m, sl)
        np.copyto(slot.block, C)
        lo, up = slot.vectors
        if lower is None:
            lo.fill(-np.inf)
        else:
            np.copyto(lo, lower)
        if upper is None:
            up.fill(np.inf)
        else:
            np.copyto(up, upper)

    def set_bounds(self, lower: Any = None, upper: Any = None) -> None:
        """Set box bounds ``lower <= x <= upper``, each (n,) with infinities allowed, None for no bound."""
        for target, value, fill, side in ((self._lb, lower, -np.inf, "lower"), (self._ub, upper, np.inf, "upper")):
            if value is None:
                target.fill(fill)
                continue
            if np.shape(value) != (self.n,):
                raise ValueError(f"WeightedQP: bounds: {side} must have shape ({self.n},), got {np.shape(value)}")
            np.copyto(target, value)
        self._has_bounds = True

    # ------------------------------------------------------------------ assembly and solve

    def build(self) -> QPProblem:
        """Assemble ``H``, ``g`` and the stacked constraints into a :class:`QPProblem`.

        The problem's arrays are views of this builder's buffers: they stay valid until the next
        :meth:`clear` / ``add_*`` call. Solve it (or copy it) before building the next tick.

        Raises:
            ValueError: non-finite cost or constraint data, or a lower bound above its upper bound; the message
                names the term.
        """
        H, g = self._H, self._g
        costs = self._costs
        if costs.rows:
            c0, c1 = costs.col_start, costs.col_stop
            J = costs.matrix[: costs.rows, c0:c1]
            if c1 - c0 < self.n:
                H.fill(0.0)
                g.fill(0.0)
            np.matmul(J.T, J, out=H[c0:c1, c0:c1])
            np.matmul(J.T, costs.vectors[0][: costs.rows], out=g[c0:c1])
        else:
            H.fill(0.0)
            g.fill(0.0)
        if self._diag_used:
            self._H_diag += self._diag_w
            g -= self._diag_wt
        check = self.check
        # A non-finite entry of J or c shows on the diagonal of H or in g (inf^2, nan, 0 * inf = nan).
        if check and not math.isfinite(float(self._H_diag.sum()) + float(g.sum())):
            self._raise_non_finite(costs, "cost")
        if self.regularization:
            self._H_diag += self.regularization
        A_eq = b_eq = C = lo = up = lb = ub = None
        if self._eqs.rows:
            A_eq, (b_eq,) = self._eqs.used()
            if check and not math.isfinite(float(A_eq.sum()) + float(b_eq.sum())):
                self._raise_non_finite(self._eqs, "equality")
        if self._ins.rows:
            C, (lo, up) = self._ins.used()
            if check and not math.isfinite(float(C.sum())):
                self._raise_non_finite(self._ins, "inequality")
            if check and not (lo <= up).all():  # also false on NaN
                slot = self._ins.slot_at_row(int(np.flatnonzero(~(lo <= up))[0]))
                raise ValueError(f"WeightedQP: inequality '{slot.name}': NaN bound, or lower bound above upper bound")
        if self._has_bounds:
            lb, ub = self._lb, self._ub
            if check and not (lb <= ub).all():
                raise ValueError("WeightedQP: bounds: NaN, or lower bound above upper bound")
        self._problem = QPProblem._trusted(H, g, A_eq, b_eq, C, lo, up, lb, ub)
        return self._problem

    def _raise_non_finite(self, stack: _Stack, what: str) -> None:
        matrix, vectors = stack.used()
        bad = ~np.isfinite(matrix).all(axis=1)
        if what != "inequality":
            for v in vectors:
                bad |= ~np.isfinite(v)
        if bad.any():
            slot = stack.slot_at_row(int(np.flatnonzero(bad)[0]))
            raise ValueError(f"WeightedQP: {what} '{slot.name}' has non-finite entries")
        for name, sl, w, t in self._diag_names:
            if t is not None and not np.isfinite(np.asarray(t, dtype=np.float64)).all():
                raise ValueError(f"WeightedQP: diagonal cost '{name}' has non-finite entries")
        raise ValueError(f"WeightedQP: {what} terms have non-finite entries (or overflow)")

    def solve(self) -> QPResult:
        """:meth:`build` then solve with this builder's backend."""
        return self.solver.solve(self.build())

    def term_costs(self, x: FloatArray) -> dict[str, float]:
        """Weighted cost of each cost term of this tick at an (n,) point ``x``, by name.

        ``w ||A x - b||^2_W`` for :meth:`add_cost` terms, ``sum_j w_j (x_j - t_j)^2`` for diagonal terms.
        """
        J, (neg_c,) = self._costs.used()
        r = J @ x + neg_c
        out = {s.name: float(r[s.start : s.stop] @ r[s.start : s.stop]) for s in self._costs.slots[: self._costs.count]}
        for name, sl, w, t in self._diag_names:
            e = x[sl] - (0.0 if t is None else np.asarray(t, dtype=np.float64))
            out[name] = float(np.sum(w * e * e))
        return out

    @property
    def problem(self) -> QPProblem | None:
        """The last problem built this tick, or None."""
        return self._problem
