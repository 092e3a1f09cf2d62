"""Tasks and priority levels of the hierarchical (lexicographic) least-squares solver."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from wbcbench.errors import QPError

__all__ = ["EqualityTask", "InequalityTask", "Level", "Task"]

FloatArray = npt.NDArray[np.float64]


def _name(name: Any, kind: str) -> str:
    if not isinstance(name, str) or not name:
        raise QPError(f"{kind}: name must be a non-empty string, got {name!r}")
    return name


def _weight(weight: Any, owner: str) -> float:
    try:
        w = float(weight)
    except (TypeError, ValueError):
        raise QPError(f"{owner}: weight must be a number, got {weight!r}") from None
    if not (math.isfinite(w) and w >= 0.0):
        raise QPError(f"{owner}: weight must be finite and >= 0, got {weight!r}")
    return w


def _matrix(value: Any, owner: str, key: str) -> FloatArray:
    array = np.asarray(value, dtype=np.float64)
    if array.ndim != 2 or array.shape[0] == 0 or array.shape[1] == 0:
        raise QPError(f"{owner}: {key} must be a non-empty 2-D array, got shape {array.shape}")
    if not np.isfinite(array).all():
        raise QPError(f"{owner}: {key} has non-finite entries")
    return array


def _vector(value: Any, owner: str, key: str, m: int, *, allow_inf: bool = False) -> FloatArray:
    array = np.asarray(value, dtype=np.float64)
    if array.shape == ():
        array = np.full(m, float(array))
    if array.shape != (m,):
        raise QPError(f"{owner}: {key} must have shape ({m},), got {array.shape}")
    if np.isnan(array).any() or (not allow_inf and not np.isfinite(array).all()):
        raise QPError(f"{owner}: {key} has {'NaN' if allow_inf else 'non-finite'} entries")
    return array


@dataclass(frozen=True, slots=True)
class EqualityTask:
    """Rows ``A x = b`` met in the least-squares sense at their level: ``weight * ||A x - b||^2``.

    Attributes:
        name: unique among all tasks given to one solve.
        A: (m, n) task matrix (task units per variable unit, e.g. a Jacobian for joint velocities in rad/s).
        b: (m,) target in task units (e.g. m/s).
        weight: relative weight among the tasks of the same level (>= 0, dimensionless); it has no effect
            across levels.
    """

    name: str
    A: FloatArray
    b: FloatArray
    weight: float = 1.0

    def __post_init__(self) -> None:
        name = _name(self.name, "EqualityTask")
        owner = f"EqualityTask '{name}'"
        A = _matrix(self.A, owner, "A")
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "b", _vector(self.b, owner, "b", A.shape[0]))
        object.__setattr__(self, "weight", _weight(self.weight, owner))

    @classmethod
    def _trusted(cls, name: str, A: FloatArray, b: FloatArray, weight: float = 1.0) -> EqualityTask:
        """Build without validation, for internal callers that guarantee the invariants (a non-empty name,
        finite float64 ``A`` (m, n) and ``b`` (m,), a finite weight >= 0), e.g. a controller handing the same
        task rows to the solver every tick."""
        self = object.__new__(cls)
        setter = object.__setattr__
        setter(self, "name", name)
        setter(self, "A", A)
        setter(self, "b", b)
        setter(self, "weight", float(weight))
        return self

    def _validate(self) -> None:
        """Run the constructor's checks (raises ValueError naming the task)."""
        self.__post_init__()

    @property
    def n_rows(self) -> int:
        return self.A.shape[0]

    @property
    def n_cols(self) -> int:
        return self.A.shape[1]

    def residual(self, x: FloatArray) -> FloatArray:
        """(m,) unweighted residual ``A x - b`` at an (n,) point ``x``, in task units."""
        return self.A @ x - self.b


@dataclass(frozen=True, slots=True)
class InequalityTask:
    """Rows ``lower <= C x <= upper`` at their level: the violation is minimised, ``weight * ||s||^2``.

    The slack formulation is ``lower <= C x - s <= upper``; the optimal ``s`` is the signed distance of
    ``C x`` to the interval (positive above ``upper``, negative below ``lower``).

    Attributes:
        name: unique among all tasks given to one solve.
        C: (m, n) constraint matrix.
        lower: (m,) lower bounds (``-inf`` allowed; a scalar is broadcast).
        upper: (m,) upper bounds (``+inf`` allowed; a scalar is broadcast), ``lower <= upper``.
        weight: relative weight among the tasks of the same level (>= 0).
    """

    name: str
    C: FloatArray
    lower: FloatArray
    upper: FloatArray
    weight: float = 1.0

    def __post_init__(self) -> None:
        name = _name(self.name, "InequalityTask")
        owner = f"InequalityTask '{name}'"
        C = _matrix(self.C, owner, "C")
        m = C.shape[0]
        lower = _vector(self.lower, owner, "lower", m, allow_inf=True)
        upper = _vector(self.upper, owner, "upper", m, allow_inf=True)
        bad = np.flatnonzero(lower > upper)
        if bad.size:
            i = int(bad[0])
            raise QPError(f"{owner}: lower above upper at row {i} ({lower[i]} > {upper[i]})")
        object.__setattr__(self, "C", C)
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        object.__setattr__(self, "weight", _weight(self.weight, owner))

    @property
    def n_rows(self) -> int:
        return self.C.shape[0]

    @property
    def n_cols(self) -> int:
        return self.C.shape[1]

    def violation(self, x: FloatArray) -> FloatArray:
        """(m,) signed violation of ``lower <= C x <= upper`` at ``x`` (0 inside, > 0 above, < 0 below)."""
        cx = self.C @ x
        return cx - np.clip(cx, self.lower, self.upper)


Task = EqualityTask | InequalityTask


@dataclass(frozen=True, slots=True)
class Level:
    """One priority level: tasks solved together, below every earlier level and above every later one.

    Attributes:
        tasks: non-empty tuple of :class:`EqualityTask` / :class:`InequalityTask` with unique names.
        name: label for reports; defaults to the task names joined by '+'.
    """

    tasks: tuple[Task, ...]
    name: str = ""

    def __post_init__(self) -> None:
        tasks = tuple(self.tasks) if isinstance(self.tasks, Iterable) else (self.tasks,)
        if not tasks:
            raise QPError(f"Level '{self.name}': empty level (give at least one task)")
        for task in tasks:
            if not isinstance(task, (EqualityTask, InequalityTask)):
                raise QPError(
                    f"Level '{self.name}': expected EqualityTask or InequalityTask, got {type(task).__name__}"
                )
        seen: set[str] = set()
        for task in tasks:
            if task.name in seen:
                raise QPError(f"Level '{self.name}': task name '{task.name}' appears twice")
            seen.add(task.name)
        n_cols = {task.n_cols for task in tasks}
        if len(n_cols) > 1:
            sizes = ", ".join(f"{t.name}: {t.n_cols}" for t in tasks)
            raise QPError(f"Level '{self.name}': tasks have different numbers of columns ({sizes})")
        object.__setattr__(self, "tasks", tasks)
        if not self.name:
            object.__setattr__(self, "name", "+".join(t.name for t in tasks))

    @classmethod
    def _trusted(cls, tasks: tuple[Task, ...], name: str) -> Level:
        """Build without validation (a non-empty tuple of tasks with unique names and equal column counts, a
        name), for internal callers that guarantee it."""
        self = object.__new__(cls)
        object.__setattr__(self, "tasks", tasks)
        object.__setattr__(self, "name", name)
        return self

    @property
    def equalities(self) -> tuple[EqualityTask, ...]:
        return tuple(t for t in self.tasks if isinstance(t, EqualityTask))

    @property
    def inequalities(self) -> tuple[InequalityTask, ...]:
        return tuple(t for t in self.tasks if isinstance(t, InequalityTask))

    @property
    def n_cols(self) -> int:
        return self.tasks[0].n_cols
