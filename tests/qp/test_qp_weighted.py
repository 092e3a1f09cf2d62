"""WeightedQP: assembly against the textbook formula, zero weights, buffer reuse, errors that name the term."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.qp import QPStatus, WeightedQP


def _naive(n, costs, diagonals, eps):
    """H = sum w A^T W A + D + eps I, g = -sum w A^T W b - D t, with every term written over all n columns."""
    H = eps * np.eye(n)
    g = np.zeros(n)
    for A, b, w, rw, cols in costs:
        full = np.zeros((A.shape[0], n))
        full[:, cols] = A
        W = w * (np.ones(A.shape[0]) if rw is None else rw)
        H += full.T @ (W[:, None] * full)
        g -= full.T @ (W * b)
    for w, t, cols in diagonals:
        H[cols, cols] += np.diag(np.broadcast_to(w, (cols.stop - cols.start,)))
        if t is not None:
            g[cols] -= w * t
    return H, g


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1))
def test_assembly_matches_the_textbook_formula(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 15))
    qp = WeightedQP(n, regularization=float(rng.choice([0.0, 1e-6, 1e-2])))
    for _ in range(3):  # the same layout over ticks reuses the slots
        costs, diagonals = [], []
        qp.clear()
        for i in range(int(rng.integers(1, 5))):
            a = int(rng.integers(0, n))
            cols = slice(a, int(rng.integers(a + 1, n + 1)))
            m = int(rng.integers(1, 6))
            A = rng.standard_normal((m, cols.stop - cols.start))
            b = rng.standard_normal(m)
            w = float(rng.choice([0.0, 0.1, 1.0, 1e3]))
            rw = rng.uniform(0, 2, m) if rng.random() < 0.3 else None
            qp.add_cost(A, b, w, row_weights=rw, cols=cols, name=f"c{i}")
            costs.append((A, b, w, rw, cols))
        if rng.random() < 0.5:
            cols = slice(0, n)
            w = rng.uniform(0, 1, n) if rng.random() < 0.5 else 0.3
            t = rng.standard_normal(n) if rng.random() < 0.5 else None
            qp.add_diagonal_cost(w, t, cols=cols, name="diag")
            diagonals.append((w, t, cols))
        p = qp.build()
        H, g = _naive(n, costs, diagonals, qp.regularization)
        np.testing.assert_allclose(p.H, H, atol=1e-9 * max(1.0, np.abs(H).max()), rtol=0)
        np.testing.assert_allclose(p.g, g, atol=1e-9 * max(1.0, np.abs(g).max()), rtol=0)
        x = rng.standard_normal(n)
        expected = sum(
            w * float(((A @ x[cols] - b) ** 2 * (1 if rw is None else rw)).sum()) for A, b, w, rw, cols in costs
        )
        assert sum(v for k, v in qp.term_costs(x).items() if k != "diag") == pytest.approx(expected, rel=1e-9, abs=1e-9)


def test_zero_weight_term_changes_nothing():
    rng = np.random.default_rng(1)
    n = 8
    A, b = rng.standard_normal((4, n)), rng.standard_normal(4)
    E, e = rng.standard_normal((2, n)), rng.standard_normal(2)
    C, u = rng.standard_normal((3, n)), np.ones(3)
    results = []
    for with_zero in (False, True):
        qp = WeightedQP(n)
        qp.add_cost(A, b, 10.0, name="task")
        if with_zero:
            qp.add_cost(rng.standard_normal((5, n)), 1e3 * rng.standard_normal(5), 0.0, name="off")
        qp.add_equality(E, e, name="eq")
        qp.add_inequality(C, upper=u, name="ineq")
        p = qp.build()
        results.append((p.H.copy(), p.g.copy(), qp.solve().unwrap()))
    np.testing.assert_array_equal(results[0][0], results[1][0])
    np.testing.assert_array_equal(results[0][1], results[1][1])
    np.testing.assert_array_equal(results[0][2], results[1][2])


def test_solution_of_an_equality_constrained_least_squares():
    """min w1 ||A1 x - b1||^2 + w2 ||A2 x - b2||^2 + eps ||x||^2 s.t. E x = e, against its KKT system."""
    rng = np.random.default_rng(2)
    n, eps = 6, 1e-6
    A1, b1 = rng.standard_normal((4, n)), rng.standard_normal(4)
    A2, b2 = rng.standard_normal((3, n)), rng.standard_normal(3)
    E, e = rng.standard_normal((2, n)), rng.standard_normal(2)
    for solver in ("daqp", "proxsuite"):
        qp = WeightedQP(n, regularization=eps, solver=solver)
        qp.add_cost(A1, b1, 3.0)
        qp.add_cost(A2, b2, 0.5)
        qp.add_equality(E, e)
        result = qp.solve()
        H = 3.0 * A1.T @ A1 + 0.5 * A2.T @ A2 + eps * np.eye(n)
        g = -(3.0 * A1.T @ b1 + 0.5 * A2.T @ b2)
        K = np.block([[H, E.T], [E, np.zeros((2, 2))]])
        x_ref = np.linalg.solve(K, np.concatenate([-g, e]))[:n]
        assert result.status is QPStatus.OPTIMAL
        np.testing.assert_allclose(result.x, x_ref, atol=1e-7)


def test_buffers_are_reused_and_grow():
    rng = np.random.default_rng(3)
    n = 5
    qp = WeightedQP(n)
    A, b = rng.standard_normal((3, n)), rng.standard_normal(3)
    qp.add_cost(A, b, 1.0, name="a")
    qp.add_equality(A[:1], b[:1], name="e")
    first = qp.build()
    H_id, C_block = id(first.H), qp._costs.slots[0].block
    qp.clear()
    qp.add_cost(2 * A, b, 1.0, name="a")
    qp.add_equality(A[:1], b[:1], name="e")
    second = qp.build()
    assert id(second.H) == H_id and qp._costs.slots[0].block is C_block  # same slot, same memory
    np.testing.assert_allclose(second.H, 4 * A.T @ A + 1e-6 * np.eye(n), atol=1e-12)
    # Many more rows than the initial capacity: the stack grows, earlier rows survive the move.
    qp.clear()
    blocks = [rng.standard_normal((30, n)) for _ in range(5)]
    for i, block in enumerate(blocks):
        qp.add_cost(block, np.zeros(30), 1.0, name=f"big{i}")
    J = np.vstack(blocks)
    np.testing.assert_allclose(qp.build().H, J.T @ J + 1e-6 * np.eye(n), atol=1e-9)
    # A different layout afterwards (fewer rows, column ranges) is still exact.
    qp.clear()
    qp.add_cost(A[:, :2], b, 1.0, cols=slice(0, 2), name="left")
    H = np.zeros((n, n))
    H[:2, :2] = A[:, :2].T @ A[:, :2]
    np.testing.assert_allclose(qp.build().H, H + 1e-6 * np.eye(n), atol=1e-12)


def test_bounds_and_inequalities_reach_the_problem():
    qp = WeightedQP(3, regularization=0.0)
    qp.add_cost(np.eye(3), np.array([5.0, 5.0, -5.0]), 1.0, name="pull")
    qp.add_inequality(np.array([[1.0, 1.0, 0.0]]), lower=-1.0, upper=1.0, name="sum")
    qp.set_bounds(np.full(3, -2.0), np.full(3, 2.0))
    x = qp.solve().unwrap()
    np.testing.assert_allclose(x, [0.5, 0.5, -2.0], atol=1e-8)  # x0 + x1 <= 1 binds, x2 at its bound
    assert qp.problem is not None and qp.problem.has_box


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda qp: qp.add_cost(np.ones((2, 3)), np.ones(2), name="com"),
         r"cost 'com': matrix must have shape \(m, 4\)"),
        (lambda qp: qp.add_cost(np.ones((2, 4)), np.ones(3), name="com"), r"cost 'com': b must have shape \(2,\)"),
        (lambda qp: qp.add_cost(np.ones((2, 4)), np.ones(2), -1.0, name="com"),
         "cost 'com': weight must be finite and >= 0"),
        (lambda qp: qp.add_cost(np.ones((2, 2)), np.ones(2), cols=slice(3, 1), name="com"), "cols must be a non-empty"),
        (lambda qp: qp.add_cost(np.ones((2, 4)), np.ones(2), row_weights=[1, -1], name="com"), "row_weights"),
        (lambda qp: qp.add_inequality(np.ones((1, 4)), name="fric"), "inequality 'fric': give lower, upper or both"),
        (lambda qp: qp.add_diagonal_cost(-1.0, name="post"), "diagonal cost 'post': weight"),
        (lambda qp: qp.set_bounds(np.zeros(3)), r"bounds: lower must have shape \(4,\)"),
    ],
)
def test_bad_input_names_the_term(call, message):
    with pytest.raises(ValueError, match=message):
        call(WeightedQP(4))


@pytest.mark.parametrize(
    ("fill", "message"),
    [
        (lambda qp: qp.add_cost(np.array([[np.nan, 0, 0, 0]]), np.zeros(1), name="com"), "cost 'com' has non-finite"),
        (lambda qp: qp.add_cost(np.eye(4), np.array([0, np.inf, 0, 0]), 0.0, name="off"), "cost 'off' has non-finite"),
        (lambda qp: qp.add_equality(np.eye(4)[:1], np.array([np.nan]), name="dyn"), "equality 'dyn' has non-finite"),
        (lambda qp: qp.add_inequality(np.eye(4)[:1], lower=2.0, upper=1.0, name="fric"), "inequality 'fric'"),
        (lambda qp: qp.add_inequality(np.eye(4)[:1], upper=np.nan, name="fric"), "inequality 'fric'"),
        (lambda qp: qp.set_bounds(np.ones(4), np.zeros(4)), "bounds"),
    ],
)
def test_non_finite_or_disordered_data_is_caught(fill, message):
    qp = WeightedQP(4)
    qp.add_cost(np.eye(4), np.ones(4), name="ok")
    with pytest.raises(ValueError, match=message):  # at the add (zero weight) or at build
        fill(qp)
        qp.build()
