"""The small interface every QP backend implements."""

from __future__ import annotations

import abc
from typing import ClassVar

from wbcbench.qp.problem import QPProblem
from wbcbench.qp.result import QPResult

__all__ = ["QPSolver"]


class QPSolver(abc.ABC):
    """A QP backend with a persistent workspace.

    An instance keeps its workspace and buffers between calls: while the problem structure (number of
    variables, of equality rows, of inequality rows, presence of box bounds) stays the same, a call only
    copies the new values in and warm-starts from the previous solution. A change of structure rebuilds the
    workspace. Use one instance per problem shape (e.g. one per hierarchy level), not one shared instance for
    problems of alternating shapes.

    Instances are not thread-safe.
    """

    name: ClassVar[str]
    """Registry name, see :func:`~wbcbench.qp.make_solver`."""

    @abc.abstractmethod
    def solve(self, problem: QPProblem) -> QPResult:
        """Solve ``problem``. Never raises for a failed solve: the status says so and ``x`` is None.

        The problem's arrays are only read during the call.
        """

    @abc.abstractmethod
    def reset(self) -> None:
        """Forget the workspace and warm start: the next :meth:`solve` starts cold."""
