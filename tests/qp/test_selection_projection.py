"""The hierarchical solver's closed-form projection (`wbcbench.qp.kernels.selection_lsq_into`, the kernel checked
against LAPACK's dgglse in test_qp_jit.py): the constraints met on random problems of its structure and on the
TALOS IK's shape, the same numbers through `selection_lsq`, and its refusals."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.qp import kernels


def selection_lsq(P, b, A, c, rank_tol):
    x = np.full(P.shape[1], np.nan)
    return kernels.selection_lsq_into(P, b, A, c, rank_tol, x), x


def _problem(rng, n, m, r, scale):
    P = rng.standard_normal((r, n)) * scale
    A = np.zeros((m, n))
    A[np.arange(m), rng.permutation(n)[:m]] = rng.uniform(0.1, 10.0, m) * rng.choice([-1.0, 1.0], m)
    return P, rng.standard_normal(r), A, rng.standard_normal(m)


@pytest.mark.parametrize("seed", range(4))
def test_random_problems_of_the_structure(seed):
    rng = np.random.default_rng(seed)
    solved = 0
    for _ in range(300):
        n = int(rng.integers(3, 45))
        m = int(rng.integers(1, n))
        k = n - m
        r = int(rng.integers(k, min(n, k + m) + 1))
        P, b, A, c = _problem(rng, n, m, r, rng.choice([1e-2, 1.0, 1e2]))
        status, x = selection_lsq(P, b, A, c, 1e-6)
        ref_status, ref_x = kernels.selection_lsq(P, b, A, c, 1e-6)
        assert status == ref_status
        assert np.array_equal(x, ref_x)
        if status == 1:
            solved += 1
            np.testing.assert_allclose(P @ x, b, atol=1e-7 * max(1.0, float(np.abs(P).max() * np.abs(x).max())))
    assert solved > 250  # random problems of this structure are almost always well posed


def test_talos_ik_shape():
    """12 + 1 + 2 + 3 dense rows over 38 variables, a 32-joint posture: the constraints met, the numbers the
    reference kernel's."""
    rng = np.random.default_rng(7)
    P = rng.standard_normal((18, 38))
    A = np.zeros((32, 38))
    A[np.arange(32), np.arange(6, 38)] = 1.0
    b, c = rng.standard_normal(18), rng.standard_normal(32)
    status, x = selection_lsq(P, b, A, c, 1e-6)
    assert status == 1
    np.testing.assert_allclose(P @ x, b, atol=1e-10)
    assert np.array_equal(x, kernels.selection_lsq(P, b, A, c, 1e-6)[1])


def test_refuses_what_it_does_not_solve():
    rng = np.random.default_rng(0)
    P, b = rng.standard_normal((4, 6)), rng.standard_normal(4)
    assert selection_lsq(P, b, rng.standard_normal((5, 6)), np.zeros(5), 1e-6)[0] == 0  # not one non-zero per row
    twice = np.zeros((2, 6))
    twice[:, 3] = 1.0
    assert selection_lsq(P, b, twice, np.zeros(2), 1e-6)[0] == 0  # the same column twice
    A = np.zeros((5, 6))
    A[np.arange(5), np.arange(1, 6)] = 1.0
    P_dep = np.vstack([P[:3], P[2]])  # dependent rows: no full row rank
    assert selection_lsq(P_dep, np.r_[b[:3], b[2]], A, np.zeros(5), 1e-6)[0] == -1
