"""What a QP backend hands back: a status enum and a frozen result container."""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from wbcbench.errors import QPError

__all__ = ["QPStatus", "QPResult", "QPSolveError"]

FloatArray = npt.NDArray[np.float64]


class QPStatus(enum.Enum):
    """Outcome of one QP solve, common to every backend.

    Only :attr:`OPTIMAL` comes with a primal solution; every other status comes with ``x = None``.
    """

    OPTIMAL = "optimal"
    """Solved to the backend's tolerances."""
    INFEASIBLE = "infeasible"
    """The constraints admit no point (primal infeasible)."""
    UNBOUNDED = "unbounded"
    """The cost decreases without bound on the feasible set (dual infeasible)."""
    MAX_ITER = "max_iter"
    """The iteration (or time) limit was reached before convergence."""
    NUMERICAL = "numerical"
    """The backend gave up for a numerical reason: cycling, a Hessian that is not positive semi-definite,
    dependent equality rows that contradict each other, a non-finite iterate, a failed set-up."""


class QPSolveError(QPError, RuntimeError):
    """Raised by :meth:`QPResult.unwrap` when a solve did not reach :attr:`QPStatus.OPTIMAL`.

    Attributes:
        result: the failed :class:`QPResult`, with the backend's own flag in ``raw_status``.
    """

    def __init__(self, result: QPResult):
        super().__init__(
            f"QP solve with backend '{result.solver}' failed: status {result.status.value} "
            f"(backend flag {result.raw_status!r}) after {result.iterations} iterations"
        )
        self.result = result


@dataclass(frozen=True, slots=True)
class QPResult:
    """Result of one QP solve.

    Attributes:
        x: (n,) primal solution in the problem's variable units when ``status`` is :attr:`QPStatus.OPTIMAL`,
            else ``None``: a failed solve never hands out an iterate. The array is owned by the result (a
            fresh copy, never a view into a solver workspace).
        status: outcome, see :class:`QPStatus`.
        iterations: iterations the backend reported (active-set changes for daqp, outer iterations for
            proxsuite).
        objective: ``1/2 x^T H x + g^T x`` at ``x`` (cost units), ``nan`` when the solve failed.
        solver: registry name of the backend (``"daqp"``, ``"proxsuite"``).
        raw_status: the backend's own flag (daqp exit flag, proxsuite ``QPSolverOutput`` name), for logs.
        working_set: the backend's final working set when it has one (an active-set method: daqp), else None:
            index arrays ``(c_up, c_lo, x_up, x_lo)`` of the inequality rows at their upper / lower bound and the
            variables at their upper / lower bound that carry a non-zero multiplier at the optimum (linearly
            independent with the equality rows, unlike every row that merely touches its bound).
    """

    x: FloatArray | None
    status: QPStatus
    iterations: int
    objective: float
    solver: str
    raw_status: int | str
    working_set: tuple | None = None

    def __post_init__(self) -> None:
        if (self.x is None) == (self.status is QPStatus.OPTIMAL):
            raise QPError(
                f"QPResult: x must be given exactly when status is OPTIMAL (status {self.status.value}, "
                f"x {'None' if self.x is None else 'given'})"
            )

    @property
    def ok(self) -> bool:
        """True when the solve reached :attr:`QPStatus.OPTIMAL` (and ``x`` is therefore set)."""
        return self.status is QPStatus.OPTIMAL

    def unwrap(self) -> FloatArray:
        """Return ``x``, or raise :class:`QPSolveError` when the solve failed."""
        if self.x is None:
            raise QPSolveError(self)
        return self.x

    @classmethod
    def failure(cls, status: QPStatus, *, solver: str, raw_status: int | str, iterations: int = 0) -> QPResult:
        """A failed result (``x = None``, ``objective = nan``)."""
        if status is QPStatus.OPTIMAL:
            raise QPError("QPResult.failure: status must not be OPTIMAL")
        return cls(None, status, int(iterations), float("nan"), solver, raw_status)
