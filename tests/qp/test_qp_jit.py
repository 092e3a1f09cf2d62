"""The compiled QP kernels (wbcbench.qp.kernels) against plain LAPACK/numpy references (reference_kernels.py): the
same decisions and the same answers, on random problems (the controllers' kernels: test_controller_kernels.py).
With WBCBENCH_JIT=0 the same kernels run as plain Python and these tests check that too."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import lapack

from wbcbench import jit
from wbcbench.qp import ActiveSetGuessSolver, DaqpSolver, HierarchicalSolver, QPProblem, kernels
from wbcbench.qp.active_set_guess import _Guess

from .qp_reference import known_qp
from .reference_kernels import certified_reference

SETTINGS = settings(max_examples=60, deadline=None, derandomize=True)


@st.composite
def qps_with_guess(draw):
    seed = draw(st.integers(0, 2**32 - 1))
    n = draw(st.integers(2, 24))
    m_eq = draw(st.integers(0, n // 2))
    m_in = draw(st.integers(0, 2 * n))
    box = draw(st.booleans())
    rng = np.random.default_rng(seed)
    known = known_qp(rng, n, m_eq, m_in, box)
    right = draw(st.booleans())  # the optimum's own active set, or a random (usually wrong) one
    return known, right, rng


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")  # the LAPACK path on a wrong guess: NaN, refused
@SETTINGS
@given(case=qps_with_guess())
def test_certified_guess_kernel_equals_the_lapack_path(case):
    known, right, rng = case
    p = known.problem
    solver = ActiveSetGuessSolver(DaqpSolver())
    if right:
        guess = solver._active_set(p, known.x_star)
    else:
        m_in = 0 if p.C is None else p.C.shape[0]
        rows = np.flatnonzero(rng.random(m_in) < 0.2)
        guess = _Guess(c_up=rows.astype(np.intp))
    m_eq = 0 if p.A_eq is None else p.A_eq.shape[0]
    numpy_answer = certified_reference(p, guess, m_eq)
    jit_answer = solver._certified(p, guess, m_eq)
    if right:
        assert numpy_answer is not None and jit_answer is not None
    assert (numpy_answer is None) == (jit_answer is None)
    if jit_answer is not None:
        scale = max(1.0, float(np.abs(numpy_answer[0]).max()))
        np.testing.assert_allclose(jit_answer[0], numpy_answer[0], atol=1e-9 * scale, rtol=0)
        assert jit_answer[1] == pytest.approx(numpy_answer[1], rel=1e-8, abs=1e-9)
        np.testing.assert_allclose(jit_answer[0], known.x_star, atol=1e-7 * scale, rtol=0)


def test_certify_kernel_rejects_nan_and_a_singular_hessian():
    H, g = np.eye(3), np.array([1.0, np.nan, 0.0])
    solver = ActiveSetGuessSolver(DaqpSolver())
    assert solver._certified(QPProblem._trusted(H, g, None, None, None, None, None, None, None), _Guess(), 0) is None
    singular = np.diag([1.0, 0.0, 1.0])
    p = QPProblem._trusted(singular, np.zeros(3), None, None, None, None, None, None, None)
    assert solver._certified(p, _Guess(), 0) is None


@st.composite
def selection_problems(draw):
    seed = draw(st.integers(0, 2**32 - 1))
    n = draw(st.integers(3, 40))
    k = draw(st.integers(0, min(6, n - 1)))  # variables left to P alone
    r = draw(st.integers(max(k, 1), max(k, 1, n - 1)))
    rng = np.random.default_rng(seed)
    P = rng.standard_normal((r, n)) * rng.choice([1e-2, 1.0, 1e2])
    m = n - k
    cols = rng.permutation(n)[:m]
    A = np.zeros((m, n))
    A[np.arange(m), cols] = rng.uniform(0.1, 10.0, m) * rng.choice([-1.0, 1.0], m)
    return P, rng.standard_normal(r), A, rng.standard_normal(m)


@SETTINGS
@given(prob=selection_problems())
def test_selection_lsq_equals_dgglse(prob):
    P, b, A, c = prob
    status, x = kernels.selection_lsq(P, b, A, c, 1e-6)
    T, R, _, x_ref, info = lapack.dgglse(A.copy(), P.copy(), c.copy(), b.copy())
    assert info == 0
    if status != 1:  # only a rank test may refuse a random problem of this structure
        assert status == -1
        return
    scale = max(1.0, float(np.abs(x_ref).max()))
    np.testing.assert_allclose(x, x_ref, atol=1e-8 * scale, rtol=0)
    np.testing.assert_allclose(P @ x, b, atol=1e-9 * max(1.0, float(np.abs(P).max()) * scale))


def test_selection_lsq_refuses_what_it_does_not_solve():
    rng = np.random.default_rng(0)
    P, b = rng.standard_normal((4, 6)), rng.standard_normal(4)
    dense = rng.standard_normal((5, 6))
    assert kernels.selection_lsq(P, b, dense, np.zeros(5), 1e-6)[0] == 0  # not one non-zero per row
    twice = np.zeros((2, 6))
    twice[:, 3] = 1.0
    assert kernels.selection_lsq(P, b, twice, np.zeros(2), 1e-6)[0] == 0  # the same column twice
    A = np.zeros((5, 6))
    A[np.arange(5), np.arange(1, 6)] = 1.0
    P_dep = np.vstack([P[:3], P[2]])  # dependent rows: no full row rank
    assert kernels.selection_lsq(P_dep, np.r_[b[:3], b[2]], A, np.zeros(5), 1e-6)[0] == -1


def test_hierarchy_closed_form_matches_a_plain_lexicographic_solve():
    """A TALOS-shaped hierarchy (12 + 1 + 2 + 3 dense rows, then a 32-joint posture) through the solver's closed
    form (the compiled posture projection) against a plain nested least-squares written here."""
    from wbcbench.qp import EqualityTask, Level

    rng = np.random.default_rng(4)
    n = 38
    posture = np.zeros((32, n))
    posture[np.arange(32), 6 + np.arange(32)] = 1.0
    rows = [(rng.standard_normal((12, n)), rng.standard_normal(12)), (rng.standard_normal((1, n)), rng.standard_normal(1)),
            (rng.standard_normal((2, n)), rng.standard_normal(2)), (rng.standard_normal((3, n)), rng.standard_normal(3)),
            (posture, rng.standard_normal(32))]
    names = ["feet", "com_z", "com_xy", "waist", "posture"]
    levels = [Level([EqualityTask(nm, A, b)]) for nm, (A, b) in zip(names, rows)]
    lb, ub = np.full(n, -1e3), np.full(n, 1e3)
    a = HierarchicalSolver(n).solve(levels, lb, ub)
    # reference: the higher levels' rows (18 independent) fix 18 directions; the posture is the least-squares
    # solution in the remaining null space (dgglse: min ||A x - c|| s.t. P x = b)
    P = np.vstack([A for A, _ in rows[:4]])
    bP = np.concatenate([b for _, b in rows[:4]])
    *_, x_ref, info = lapack.dgglse(posture.copy(), P.copy(), rows[4][1].copy(), bP.copy())
    assert info == 0
    np.testing.assert_allclose(a.x, x_ref, atol=1e-10)
    assert a.met == tuple(r.met for r in a.levels)


def test_environment_switch_turns_the_kernels_off():
    code = "from wbcbench import jit; print(jit.JIT_ENABLED)"
    env = {**os.environ, "WBCBENCH_JIT": "0"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
