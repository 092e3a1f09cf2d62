"""Named containers for what tasks and contacts hand to a formulation."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

__all__ = ["Rows", "Inequality"]


class Rows(NamedTuple):
    """Task rows ``A x = b`` in the formulation's variable space (least squares when soft, equality when hard).

    Attributes:
        A: (m, nv) matrix; ``m`` is the number of axes selected by the task mask, ``nv`` the model's.
            At acceleration level ``x`` is the joint acceleration ``dv`` and A is the task Jacobian; at
            velocity level ``x`` is the joint velocity ``v``. May be a read-only array: copy before writing.
        b: (m,) vector in the task's units per s^2 (acceleration level) or per s (velocity level).
    """

    A: npt.NDArray[np.float64]
    b: npt.NDArray[np.float64]


class Inequality(NamedTuple):
    """Linear inequality ``C w <= u`` on a contact wrench.

    Attributes:
        C: (k, 6) matrix acting on the wrench ``w = [f; tau]`` (N, N m) expressed in the contact frame at its
            origin. Read-only.
        u: (k,) upper bounds (N or N m). Read-only.
    """

    C: npt.NDArray[np.float64]
    u: npt.NDArray[np.float64]
