"""The QP every backend solves, as one validated container."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from wbcbench.errors import QPError

__all__ = ["QPProblem"]

FloatArray = npt.NDArray[np.float64]


def _matrix(value: Any, name: str, rows: int | None, cols: int) -> FloatArray:
    array = np.asarray(value, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != cols or (rows is not None and array.shape[0] != rows):
        want = f"({'m' if rows is None else rows}, {cols})"
        raise QPError(f"QPProblem: {name} must have shape {want}, got {array.shape}")
    if not np.isfinite(array).all():
        raise QPError(f"QPProblem: {name} has non-finite entries")
    return array


def _vector(value: Any, name: str, size: int, *, fill: float | None = None, finite: bool = True) -> FloatArray:
    if value is None:
        if fill is None:
            raise QPError(f"QPProblem: {name} is required")
        return np.full(size, fill)
    array = np.asarray(value, dtype=np.float64)
    if array.shape != (size,):
        raise QPError(f"QPProblem: {name} must have shape ({size},), got {array.shape}")
    if np.isnan(array).any() or (finite and not np.isfinite(array).all()):
        raise QPError(f"QPProblem: {name} has {'non-finite' if finite else 'NaN'} entries")
    return array


def _check_order(lower: FloatArray, upper: FloatArray, what: str) -> None:
    bad = np.flatnonzero(lower > upper)
    if bad.size:
        i = int(bad[0])
        raise QPError(
            f"QPProblem: {what} lower bound above upper bound at row {i} ({lower[i]} > {upper[i]}); "
            f"{bad.size} such row(s)"
        )


@dataclass(frozen=True, slots=True)
class QPProblem:
    """Convex QP ``min 1/2 x^T H x + g^T x`` s.t. ``A_eq x = b_eq``, ``l <= C x <= u``, ``lb <= x <= ub``.

    Only ``H`` and ``g`` are required; absent constraints are ``None``. Infinite entries in ``l``, ``u``,
    ``lb``, ``ub`` mean "no bound on this side". The constructor validates shapes, finiteness and bound order
    once and stores float64 arrays; it does not copy arrays that already are float64, so the caller must not
    mutate them while a solve uses them.

    Attributes:
        H: (n, n) symmetric positive semi-definite Hessian (cost units per variable unit squared). daqp needs
            it positive definite for an exact solve (a singular H triggers its proximal iterations).
        g: (n,) linear cost.
        A_eq: (m_eq, n) equality matrix, or None.
        b_eq: (m_eq,) equality right-hand side, or None.
        C: (m_in, n) inequality matrix, or None.
        l: (m_in,) lower bounds on ``C x`` (``-inf`` allowed), or None.
        u: (m_in,) upper bounds on ``C x`` (``+inf`` allowed), or None.
        lb: (n,) lower bounds on ``x`` (``-inf`` allowed), or None.
        ub: (n,) upper bounds on ``x`` (``+inf`` allowed), or None.

    With ``C`` given, a missing ``l`` (``u``) means ``-inf`` (``+inf``); with one of ``lb``, ``ub`` given the
    other defaults to the matching infinity.
    """

    H: FloatArray
    g: FloatArray
    A_eq: FloatArray | None = None
    b_eq: FloatArray | None = None
    C: FloatArray | None = None
    l: FloatArray | None = None  # noqa: E741 (the usual name)
    u: FloatArray | None = None
    lb: FloatArray | None = None
    ub: FloatArray | None = None

    def __post_init__(self) -> None:
        H = np.asarray(self.H, dtype=np.float64)
        if H.ndim != 2 or H.shape[0] != H.shape[1] or H.shape[0] == 0:
            raise QPError(f"QPProblem: H must be a non-empty square matrix, got shape {H.shape}")
        n = H.shape[0]
        H = _matrix(H, "H", n, n)
        values: dict[str, Any] = {"H": H, "g": _vector(self.g, "g", n)}
        if (self.A_eq is None) != (self.b_eq is None):
            raise QPError("QPProblem: A_eq and b_eq must be given together")
        if self.A_eq is not None:
            A_eq = _matrix(self.A_eq, "A_eq", None, n)
            values["A_eq"] = A_eq
            values["b_eq"] = _vector(self.b_eq, "b_eq", A_eq.shape[0])
        if self.C is None:
            if self.l is not None or self.u is not None:
                raise QPError("QPProblem: l or u given without C")
        else:
            C = _matrix(self.C, "C", None, n)
            m = C.shape[0]
            values["C"] = C
            values["l"] = _vector(self.l, "l", m, fill=-np.inf, finite=False)
            values["u"] = _vector(self.u, "u", m, fill=np.inf, finite=False)
            _check_order(values["l"], values["u"], "inequality")
        if self.lb is not None or self.ub is not None:
            values["lb"] = _vector(self.lb, "lb", n, fill=-np.inf, finite=False)
            values["ub"] = _vector(self.ub, "ub", n, fill=np.inf, finite=False)
            _check_order(values["lb"], values["ub"], "box")
        for key, value in values.items():
            object.__setattr__(self, key, value)

    @classmethod
    def _trusted(
        cls,
        H: FloatArray,
        g: FloatArray,
        A_eq: FloatArray | None = None,
        b_eq: FloatArray | None = None,
        C: FloatArray | None = None,
        l: FloatArray | None = None,  # noqa: E741
        u: FloatArray | None = None,
        lb: FloatArray | None = None,
        ub: FloatArray | None = None,
    ) -> QPProblem:
        """Build without validation, for the builders of this package that guarantee the invariants.

        Same invariants as the public constructor: float64 arrays of matching shapes, ``l``/``u`` both set
        when ``C`` is, ``lb``/``ub`` both set or both None.
        """
        self = object.__new__(cls)
        setter = object.__setattr__
        setter(self, "H", H)
        setter(self, "g", g)
        setter(self, "A_eq", A_eq)
        setter(self, "b_eq", b_eq)
        setter(self, "C", C)
        setter(self, "l", l)
        setter(self, "u", u)
        setter(self, "lb", lb)
        setter(self, "ub", ub)
        return self

    @property
    def n(self) -> int:
        """Number of variables."""
        return self.H.shape[0]

    @property
    def n_eq(self) -> int:
        """Number of equality rows."""
        return 0 if self.A_eq is None else self.A_eq.shape[0]

    @property
    def n_in(self) -> int:
        """Number of two-sided inequality rows (box bounds not counted)."""
        return 0 if self.C is None else self.C.shape[0]

    @property
    def has_box(self) -> bool:
        """True when the problem carries box bounds ``lb <= x <= ub``."""
        return self.lb is not None

    def objective(self, x: FloatArray) -> float:
        """``1/2 x^T H x + g^T x`` for an (n,) point ``x``."""
        return float(0.5 * x @ self.H @ x + self.g @ x)
