"""The hierarchical solver's bound kernels (`kernels.bounds_ordered`, `kernels.bounds_and_residuals`) against numpy,
and the position schemes' velocity integration (`inverse_dynamics._integrate_velocity`) against the numpy
expression it replaces, bit for bit."""

from __future__ import annotations

import numpy as np

from wbcbench.controllers.inverse_dynamics import _integrated_velocity
from wbcbench.qp import kernels


def test_bounds_ordered_is_numpys_comparison():
    rng = np.random.default_rng(0)
    lb = rng.normal(size=38) - 1.0
    ub = lb + rng.uniform(0.0, 1.0, size=38)
    ub[[0, 37]] = np.inf
    lb[5] = -np.inf
    assert kernels.bounds_ordered(lb, ub) and (lb <= ub).all()
    for i, bad in ((3, np.nan), (20, np.inf), (10, 1e9)):
        low = lb.copy()
        low[i] = bad
        assert not kernels.bounds_ordered(low, ub)
        assert not (low <= ub).all()
    equal = lb.copy()
    assert kernels.bounds_ordered(equal, equal)


def test_bounds_and_residuals_match_numpy():
    rng = np.random.default_rng(1)
    n = 12
    A, b, x = rng.normal(size=(9, n)), rng.normal(size=9), rng.normal(size=n)
    starts = np.array([0, 2, 5, 6], dtype=np.intp)
    block_level = np.array([0, 0, 1, 2], dtype=np.intp)
    lb, ub = x - rng.uniform(0, 1, n), x + rng.uniform(0, 1, n)
    lb[4], ub[7] = x[4] + 0.25, x[7] - 0.5
    sums, level_sums = np.full(4, np.nan), np.full(3, np.nan)
    high, low = kernels.bounds_and_residuals(A, b, x, starts, block_level, lb, ub, sums, level_sums)
    assert high == np.max(x - ub) and low == np.max(lb - x)
    expected = np.add.reduceat((A @ x - b) ** 2, starts)
    np.testing.assert_allclose(sums, expected, rtol=1e-13)
    np.testing.assert_allclose(level_sums, [expected[0] + expected[1], expected[2], expected[3]], rtol=1e-13)
    x[3] = np.nan  # not finite: NaN violations, zero sums
    high, low = kernels.bounds_and_residuals(A, b, x, starts, block_level, lb, ub, sums, level_sums)
    assert np.isnan(high) and np.isnan(low)
    assert not sums.any() and not level_sums.any()


def test_integrated_velocity_is_the_numpy_expression_bit_for_bit():
    rng = np.random.default_rng(2)
    step = np.empty(50)
    for dt in (1e-3, 2e-3, 1.0 / 3.0):
        v, dv = rng.normal(size=50), 100.0 * rng.normal(size=50)
        v_new, out = _integrated_velocity(v, dv, dt, step)
        assert out is step
        assert np.array_equal(v_new, v + dv * dt)
        assert np.array_equal(out, (v + dv * dt) * dt)
        assert v_new is not v
