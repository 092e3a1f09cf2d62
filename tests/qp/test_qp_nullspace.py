"""The pivoted-QR null-space step against numpy's SVD-based pseudo-inverse."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.qp._nullspace import least_squares_step, project


@settings(max_examples=50, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), damping=st.sampled_from([0.0, 1e-3, 0.5]))
def test_step_and_null_space_match_the_pseudo_inverse(seed, damping):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 12))
    d = int(rng.integers(1, n + 1))
    m = int(rng.integers(1, 14))
    Z = None if d == n and rng.random() < 0.5 else np.linalg.qr(rng.standard_normal((n, d)))[0]
    d = n if Z is None else d
    A = rng.standard_normal((m, n))
    if m >= 3 and rng.random() < 0.5:
        A[-1] = A[0] - 2 * A[1]  # rank-deficient
    basis = np.eye(n) if Z is None else Z
    M = A @ basis
    r = rng.standard_normal(m)
    proj = project(M, Z, 1e-9 * np.linalg.norm(A))
    assert proj.rank == np.linalg.matrix_rank(M, tol=1e-9 * np.linalg.norm(A))
    ZQ = proj.ZQ
    np.testing.assert_allclose(ZQ.T @ ZQ, np.eye(d), atol=1e-12)  # orthonormal
    np.testing.assert_allclose(basis @ (basis.T @ ZQ), ZQ, atol=1e-12)  # within the span of Z
    np.testing.assert_allclose(A @ ZQ[:, proj.rank :], 0.0, atol=1e-12 * max(1.0, np.linalg.norm(A)))  # null space
    step = ZQ[:, : proj.rank] @ least_squares_step(proj, r, damping) if proj.rank else np.zeros(n)
    if damping:
        w = np.linalg.solve(M.T @ M + damping**2 * np.eye(d), M.T @ r)
    else:
        w = np.linalg.pinv(M, rcond=1e-12) @ r  # minimum-norm least squares
    np.testing.assert_allclose(step, basis @ w, atol=1e-9 * max(1.0, np.abs(w).max()))
