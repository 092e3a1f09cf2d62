"""Explicit registry of QP backends, keyed by name."""

from __future__ import annotations

from wbcbench.errors import QPError
from wbcbench.qp.daqp_solver import DaqpSolver
from wbcbench.qp.proxsuite_solver import ProxsuiteSolver
from wbcbench.qp.solver import QPSolver

__all__ = ["SOLVERS", "DEFAULT_SOLVER", "make_solver", "solver_names"]

SOLVERS: dict[str, type[QPSolver]] = {
    DaqpSolver.name: DaqpSolver,
    ProxsuiteSolver.name: ProxsuiteSolver,
}
"""Backend name -> class. Read-only by convention; :func:`solver_names` lists the keys."""

DEFAULT_SOLVER = DaqpSolver.name


def solver_names() -> tuple[str, ...]:
    """Registered backend names, sorted."""
    return tuple(sorted(SOLVERS))


def make_solver(name: str = DEFAULT_SOLVER, **options: object) -> QPSolver:
    """A new backend instance (with its own workspace) by registry name.

    Args:
        name: ``"daqp"`` (default) or ``"proxsuite"``.
        **options: keyword arguments of the backend's constructor, e.g. ``eps_abs=1e-9`` for proxsuite,
            ``primal_tol=1e-9`` for daqp.

    Raises:
        ValueError: unknown name (the message lists the valid ones) or an option the backend refuses.
    """
    try:
        cls = SOLVERS[name]
    except (KeyError, TypeError):
        raise QPError(f"unknown QP solver {name!r}; valid: {', '.join(solver_names())}") from None
    try:
        return cls(**options)  # type: ignore[arg-type]
    except TypeError as exc:
        raise QPError(f"QP solver {name!r}: {exc}") from None
