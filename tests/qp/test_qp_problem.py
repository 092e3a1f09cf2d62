"""QPProblem validation and the QPResult contract."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.qp import QPProblem, QPResult, QPSolveError, QPStatus


def _base(n: int = 3) -> dict[str, np.ndarray]:
    return {"H": np.eye(n), "g": np.ones(n)}


def test_minimal_problem_has_no_constraints():
    p = QPProblem(**_base())
    assert (p.n, p.n_eq, p.n_in, p.has_box) == (3, 0, 0, False)
    assert p.objective(np.zeros(3)) == 0.0


def test_one_sided_bounds_are_filled_with_infinities():
    p = QPProblem(**_base(), C=np.ones((2, 3)), u=np.array([1.0, 2.0]), lb=np.zeros(3))
    np.testing.assert_array_equal(p.l, [-np.inf, -np.inf])
    np.testing.assert_array_equal(p.ub, [np.inf] * 3)
    assert p.n_in == 2 and p.has_box


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({"H": np.ones((2, 3))}, "square"),
        ({"g": np.ones(2)}, "g must have shape"),
        ({"A_eq": np.ones((1, 3))}, "together"),
        ({"A_eq": np.ones((1, 2)), "b_eq": np.ones(1)}, "A_eq must have shape"),
        ({"A_eq": np.ones((1, 3)), "b_eq": np.ones(2)}, "b_eq must have shape"),
        ({"l": np.ones(1)}, "without C"),
        ({"C": np.ones((1, 3)), "l": np.array([2.0]), "u": np.array([1.0])}, "lower bound above upper"),
        ({"lb": np.ones(3), "ub": np.zeros(3)}, "box lower bound above upper"),
        ({"H": np.array([[1.0, 0, 0], [0, np.nan, 0], [0, 0, 1]])}, "non-finite"),
        ({"g": np.array([0.0, np.inf, 0.0])}, "non-finite"),
        ({"C": np.ones((1, 3)), "u": np.array([np.nan])}, "NaN"),
    ],
)
def test_invalid_problems_raise(extra, message):
    kwargs = {**_base(), **extra}
    with pytest.raises(ValueError, match=message):
        QPProblem(**kwargs)


def test_result_contract_x_only_when_optimal():
    with pytest.raises(ValueError, match="exactly when status is OPTIMAL"):
        QPResult(None, QPStatus.OPTIMAL, 0, 0.0, "daqp", 1)
    with pytest.raises(ValueError, match="exactly when status is OPTIMAL"):
        QPResult(np.zeros(2), QPStatus.INFEASIBLE, 0, 0.0, "daqp", -1)
    failed = QPResult.failure(QPStatus.MAX_ITER, solver="daqp", raw_status=-4, iterations=7)
    assert not failed.ok and failed.x is None and np.isnan(failed.objective)
    with pytest.raises(QPSolveError, match="max_iter") as info:
        failed.unwrap()
    assert info.value.result is failed
    ok = QPResult(np.zeros(2), QPStatus.OPTIMAL, 3, 0.0, "daqp", 1)
    assert ok.ok and ok.unwrap() is ok.x
