"""ActiveSetGuessSolver: a guess is only ever accepted with a KKT certificate, so its answers are the backend's."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.qp import ActiveSetGuessSolver, DaqpSolver, QPProblem, QPResult, QPStatus

from .qp_reference import known_qp

SETTINGS = settings(max_examples=50, deadline=None, derandomize=True)


def _perturbed(problem: QPProblem, rng: np.random.Generator, scale: float) -> QPProblem:
    """The same problem with a perturbed cost (the active set may or may not change)."""
    return QPProblem(problem.H, problem.g + scale * rng.standard_normal(problem.n), problem.A_eq, problem.b_eq,
                     problem.C, problem.l, problem.u, problem.lb, problem.ub)


@st.composite
def sequences(draw):
    seed = draw(st.integers(0, 2**32 - 1))
    n = draw(st.integers(2, 20))
    m_eq = draw(st.integers(0, n // 2))
    m_in = draw(st.integers(0, 2 * n))
    box = draw(st.booleans())
    scale = draw(st.sampled_from([0.0, 1e-3, 0.1, 1.0]))
    rng = np.random.default_rng(seed)
    return known_qp(rng, n, m_eq, m_in, box), rng, scale


@SETTINGS
@given(seq=sequences())
def test_every_answer_is_the_cold_backends(seq):
    """A sequence of related problems (same structure, moving cost): each answer equals a cold daqp solve,
    whether it came from the certified guess or from the backend."""
    known, rng, scale = seq
    solver = ActiveSetGuessSolver(DaqpSolver())
    problem = known.problem
    for _ in range(6):
        result = solver.solve(problem)
        reference = DaqpSolver().solve(problem)
        assert result.status is reference.status
        x_scale = max(1.0, float(np.abs(reference.x).max()))
        np.testing.assert_allclose(result.x, reference.x, atol=1e-8 * x_scale, rtol=0)
        assert result.objective == pytest.approx(problem.objective(result.x), rel=1e-6, abs=1e-6)
        problem = _perturbed(problem, rng, scale)
    assert solver.n_guessed + solver.n_backend == 6


def test_same_problem_again_is_answered_by_the_guess_and_owns_its_x():
    rng = np.random.default_rng(3)
    known = known_qp(rng, 12, 3, 20, True)
    assert known.n_active > 0
    solver = ActiveSetGuessSolver(DaqpSolver())
    first = solver.solve(known.problem)
    assert solver.n_backend == 1 and first.raw_status != "guess"
    second = solver.solve(known.problem)
    assert solver.n_guessed == 1 and second.raw_status == "guess"
    np.testing.assert_allclose(second.x, known.x_star, atol=1e-9)
    kept = second.x.copy()
    solver.solve(_perturbed(known.problem, rng, 0.5))
    np.testing.assert_array_equal(second.x, kept)  # a later solve does not write into an earlier result


def test_a_wrong_guess_is_never_accepted():
    """The active set changes completely: the guess fails its certificate and the backend answers."""
    H, g = np.eye(2), np.array([-1.0, -1.0])  # unconstrained optimum (1, 1)
    box = dict(lb=np.full(2, -0.5), ub=np.full(2, 0.5))
    solver = ActiveSetGuessSolver(DaqpSolver())
    np.testing.assert_allclose(solver.solve(QPProblem(H, g, **box)).x, [0.5, 0.5], atol=1e-12)  # both at ub
    flipped = solver.solve(QPProblem(H, -g, **box))  # optimum at lb now: the guessed rows are wrong
    np.testing.assert_allclose(flipped.x, [-0.5, -0.5], atol=1e-12)
    assert solver.n_guessed == 0 and solver.n_backend == 2
    inside = solver.solve(QPProblem(H, 0.1 * g, **box))  # guess (both at lb) has multipliers of the wrong sign
    np.testing.assert_allclose(inside.x, [0.1, 0.1], atol=1e-12)
    assert solver.n_guessed == 0


def test_failures_come_from_the_backend():
    row = np.array([[1.0, 0, 0]])
    problem = QPProblem(np.eye(3), np.zeros(3), C=row, l=np.array([2.0]), lb=-np.ones(3), ub=np.ones(3))
    result = ActiveSetGuessSolver(DaqpSolver()).solve(problem)
    assert result.status is QPStatus.INFEASIBLE and result.x is None


def test_singular_hessian_goes_to_the_backend():
    problem = QPProblem(np.diag([1.0, 0.0]), np.array([-1.0, 0.0]), lb=-np.ones(2), ub=np.ones(2))
    solver = ActiveSetGuessSolver(DaqpSolver())
    result = solver.solve(problem)
    assert isinstance(result, QPResult) and result.ok and solver.n_backend == 1
    assert result.x[0] == pytest.approx(1.0, abs=1e-6)


def test_nearly_dependent_guessed_rows_go_to_the_backend():
    """Two active rows parallel to 1e-9: the range-space solve of the guess is inaccurate (its multipliers
    blow up); the primal test refuses it instead of returning a point off the constraints."""
    C = np.array([[1.0, 0.0, 0.0], [1.0, 1e-9, 0.0], [0.0, 0.0, 1.0]])
    problem = QPProblem(np.eye(3), np.array([-2.0, 0.0, -1.0]), C=C, u=np.array([1.0, 1.0, 0.5]))
    solver = ActiveSetGuessSolver(DaqpSolver())
    for _ in range(3):
        result = solver.solve(problem)
        reference = DaqpSolver().solve(problem)
        np.testing.assert_allclose(result.x, reference.x, atol=1e-8)
        assert np.all(C @ result.x <= problem.u + 1e-9)


def test_the_backends_working_set_is_the_next_guess_where_touching_rows_are_dependent():
    """Two copies of a row both touch their bound at the optimum: every row within tolerance of its bound makes
    a singular Gram matrix, so that guess can never be certified; daqp's working set (one copy, the one with a
    multiplier) is independent, and the same problem again is answered by the guess."""
    C = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    problem = QPProblem(np.eye(2), np.array([-2.0, 0.0]), C=C, u=np.array([1.0, 1.0, 5.0]))
    solver = ActiveSetGuessSolver(DaqpSolver())
    first = solver.solve(problem)
    np.testing.assert_allclose(first.x, [1.0, 0.0], atol=1e-12)
    touching = solver._active_set(problem, first.x)
    assert touching.c_up.tolist() == [0, 1]  # dependent: the old guess
    c_up, c_lo, x_up, x_lo = first.working_set
    assert len(c_up) == 1 and c_up[0] in (0, 1) and not (len(c_lo) or len(x_up) or len(x_lo))
    again = solver.solve(problem)
    assert again.raw_status == "guess" and solver.n_guessed == 1
    np.testing.assert_allclose(again.x, first.x, atol=1e-12)


def test_daqps_working_set_holds_its_rows_at_their_bounds():
    rng = np.random.default_rng(5)
    for _ in range(20):
        known = known_qp(rng, 12, 3, 20, True)
        result = DaqpSolver().solve(known.problem)
        p, x = known.problem, result.x
        c_up, c_lo, x_up, x_lo = result.working_set
        cx = p.C @ x
        np.testing.assert_allclose(cx[c_up], p.u[c_up], atol=1e-9)
        np.testing.assert_allclose(cx[c_lo], p.l[c_lo], atol=1e-9)
        np.testing.assert_allclose(x[x_up], p.ub[x_up], atol=1e-9)
        np.testing.assert_allclose(x[x_lo], p.lb[x_lo], atol=1e-9)
        # independent with the equality rows: at most n - m_eq of them
        assert len(c_up) + len(c_lo) + len(x_up) + len(x_lo) <= p.H.shape[0] - p.A_eq.shape[0]
