"""QP layer: a problem container, two backends behind one interface, a hierarchical solver.

- :class:`QPProblem`: ``min 1/2 x^T H x + g^T x`` s.t. ``A_eq x = b_eq``, ``l <= C x <= u``, ``lb <= x <= ub``.
- :class:`QPSolver` with :class:`DaqpSolver` (default) and :class:`ProxsuiteSolver`; :func:`make_solver` by name;
  :class:`ActiveSetGuessSolver` in front of one for QPs solved again and again (a controller's tick).
- :class:`QPResult` with a :class:`QPStatus`; ``x`` is None unless the solve is optimal.
  The weighted inverse-dynamics QP is assembled by `wbcbench.controllers.id_formulation` (one builder).
- :class:`HierarchicalSolver`: strict (lexicographic) priorities over :class:`Level` of
  :class:`EqualityTask` and :class:`InequalityTask`, under hard bounds.
"""

from wbcbench.qp.active_set_guess import ActiveSetGuessSolver
from wbcbench.qp.daqp_solver import DaqpSolver
from wbcbench.qp.hierarchical import HierarchicalResult, HierarchicalSolver, LevelPath, LevelReport
from wbcbench.qp.levels import EqualityTask, InequalityTask, Level
from wbcbench.qp.problem import QPProblem
from wbcbench.qp.proxsuite_solver import ProxsuiteSolver
from wbcbench.qp.registry import DEFAULT_SOLVER, make_solver, solver_names
from wbcbench.qp.result import QPResult, QPSolveError, QPStatus
from wbcbench.qp.solver import QPSolver

__all__ = [
    "DEFAULT_SOLVER",
    "ActiveSetGuessSolver",
    "DaqpSolver",
    "EqualityTask",
    "HierarchicalResult",
    "HierarchicalSolver",
    "InequalityTask",
    "Level",
    "LevelPath",
    "LevelReport",
    "ProxsuiteSolver",
    "QPProblem",
    "QPResult",
    "QPSolveError",
    "QPSolver",
    "QPStatus",
    "make_solver",
    "solver_names",
]
