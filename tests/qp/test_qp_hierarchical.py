"""HierarchicalSolver: strict priorities, against a slow reference cascade, on random draws."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from wbcbench.qp import EqualityTask, HierarchicalSolver, InequalityTask, Level, LevelPath

from .qp_reference import level_residuals, random_hierarchy, reference_hierarchy

SETTINGS = settings(max_examples=50, deadline=None, derandomize=True)


@st.composite
def hierarchies(draw, with_inequalities: bool = True):
    seed = draw(st.integers(0, 2**32 - 1))
    n = draw(st.integers(2, 12))
    n_levels = draw(st.integers(1, 4))
    bound_scale = draw(st.sampled_from([0.3, 1.0, 10.0]))  # bounds that bind, sometimes, never
    rng = np.random.default_rng(seed)
    return (n, *random_hierarchy(rng, n, n_levels, bound_scale=bound_scale, with_inequalities=with_inequalities))


def _scale(x: np.ndarray) -> float:
    return max(1.0, float(np.abs(x).max()))


def _reference(levels, lb, ub, **options) -> np.ndarray:
    """The slow cascade; a draw it cannot solve (its explicit constraints are fragile, see its docstring;
    about 1 in 1000 damped draws) is rejected rather than failed."""
    try:
        return reference_hierarchy(levels, lb, ub, **options)
    except RuntimeError:
        assume(False)
        raise  # unreachable


@SETTINGS
@given(problem=hierarchies())
def test_matches_the_slow_reference_cascade(problem):
    """Same x as one full-space QP per level with the levels above as explicit constraints (1e-6)."""
    n, levels, lb, ub = problem
    x_ref = _reference(levels, lb, ub)
    for options in ({}, {"fast_path": False}):
        result = HierarchicalSolver(n, **options).solve(levels, lb, ub)
        assert result.ok, result.report()
        np.testing.assert_allclose(result.x, x_ref, atol=1e-6 * _scale(x_ref), rtol=0, err_msg=str(options))


@SETTINGS
@given(problem=hierarchies())
def test_adding_a_lower_level_never_changes_a_higher_residual(problem):
    n, levels, lb, ub = problem
    solver = HierarchicalSolver(n)
    previous = None
    for k in range(1, len(levels) + 1):
        result = solver.solve(levels[:k], lb, ub)
        residuals = [r.residual for r in result.levels]
        np.testing.assert_allclose(residuals, level_residuals(levels[:k], result.x), atol=1e-12, rtol=1e-12)
        if previous is not None:
            np.testing.assert_allclose(residuals[: k - 1], previous, atol=1e-8, rtol=0)
        previous = residuals


@SETTINGS
@given(problem=hierarchies())
def test_bounds_are_never_violated(problem):
    n, levels, lb, ub = problem
    for options in ({}, {"fast_path": False}, {"damping": 0.1}):
        x = HierarchicalSolver(n, **options).solve(levels, lb, ub).x
        assert np.all(x >= lb - 1e-9) and np.all(x <= ub + 1e-9)


@settings(max_examples=25, deadline=None, derandomize=True)
@given(problem=hierarchies(), damping=st.sampled_from([1e-3, 0.1, 1.0]))
def test_damping_matches_the_damped_reference(problem, damping):
    n, levels, lb, ub = problem
    x_ref = _reference(levels, lb, ub, damping=damping)
    x = HierarchicalSolver(n, damping=damping).solve(levels, lb, ub).x
    np.testing.assert_allclose(x, x_ref, atol=1e-6 * _scale(x_ref), rtol=0)


@settings(max_examples=25, deadline=None, derandomize=True)
@given(problem=hierarchies(with_inequalities=False))
def test_proxsuite_backend_agrees_when_it_succeeds(problem):
    """The proxsuite backend is less robust on degenerate level QPs (see ProxsuiteSolver); when every level
    solved, it agrees with daqp. A failure is always reported (ok False), never silent."""
    n, levels, lb, ub = problem
    reference = HierarchicalSolver(n).solve(levels, lb, ub)
    result = HierarchicalSolver(n, solver="proxsuite").solve(levels, lb, ub)
    if result.ok:
        np.testing.assert_allclose(result.x, reference.x, atol=1e-5 * _scale(reference.x), rtol=0)
    else:
        assert any(r.path is LevelPath.FAILED for r in result.levels) or result.final_path is LevelPath.FAILED


def test_strict_priority_level_one_wins_exactly():
    """Level 1: x0 + x1 = 1. Level 2 wants x0 + x1 = 3 and x0 - x1 = 0.5: only the second row can be met."""
    levels = [
        Level((EqualityTask("sum", np.array([[1.0, 1.0]]), np.array([1.0])),)),
        Level((EqualityTask("conflict", np.array([[1.0, 1.0], [1.0, -1.0]]), np.array([3.0, 0.5])),)),
    ]
    for options in ({}, {"fast_path": False}):
        result = HierarchicalSolver(2, **options).solve(levels)
        np.testing.assert_allclose(result.x, [0.75, 0.25], atol=1e-12)
        first, second = result.levels
        assert first.residual < 1e-14 and first.met
        assert second.residual == pytest.approx(2.0, abs=1e-12) and not second.met
        assert (first.rank, second.rank) == (1, 1)
        assert (first.freedom, second.freedom) == (2, 1)
        assert result.final_path is LevelPath.LOCKED
    # Without level 1, level 2 alone is met: the hierarchy, not the data, made it fail.
    assert HierarchicalSolver(2).solve(levels[1:]).levels[0].met


def test_unreachable_target_degrades_to_least_squares_under_bounds():
    """x0 = 5 is out of reach with x0 <= 1: met as well as the bound allows; the next level keeps its freedom."""
    levels = [
        Level((EqualityTask("reach", np.array([[1.0, 0.0, 0.0]]), np.array([5.0])),)),
        Level((EqualityTask("rest", np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), np.array([0.2, -0.3])),)),
    ]
    result = HierarchicalSolver(3).solve(levels, -np.ones(3), np.ones(3))
    np.testing.assert_allclose(result.x, [1.0, 0.2, -0.3], atol=1e-9)
    reach, rest = result.levels
    assert reach.path is LevelPath.QP and not reach.met and reach.residual == pytest.approx(4.0)
    assert rest.met and result.ok
    assert "reach" in result.report() and "NO" in result.report()


def test_inequality_task_violation_is_minimised_and_kept():
    """Level 1: 2 <= x0 + x1 <= 3 against the box x <= 0.5 (violation 1 at best); level 2 cannot undo it."""
    levels = [
        Level((InequalityTask("band", np.array([[1.0, 1.0]]), 2.0, 3.0),)),
        Level((EqualityTask("pull", np.array([[1.0, 0.0]]), np.array([-1.0])),)),
    ]
    result = HierarchicalSolver(2).solve(levels, np.full(2, -1.0), np.full(2, 0.5))
    np.testing.assert_allclose(result.x, [0.5, 0.5], atol=1e-9)
    band, pull = result.levels
    assert band.residual == pytest.approx(1.0, abs=1e-9) and not band.met
    assert band.rank == 1  # the violated row is fixed for the levels below
    assert pull.residual == pytest.approx(1.5, abs=1e-9)


def test_fast_path_when_nothing_binds_and_min_norm_completion():
    rng = np.random.default_rng(4)
    A = rng.standard_normal((2, 5))
    levels = [Level((EqualityTask("task", A, np.array([0.1, -0.2])),))]
    result = HierarchicalSolver(5).solve(levels, -np.ones(5) * 10, np.ones(5) * 10)
    assert result.levels[0].path is LevelPath.NULLSPACE and result.final_path is LevelPath.NULLSPACE
    np.testing.assert_allclose(result.x, np.linalg.pinv(A) @ np.array([0.1, -0.2]), atol=1e-12)


def test_rank_deficient_level_reports_its_rank():
    A = np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 1.0]])  # rank 2
    result = HierarchicalSolver(3).solve([[EqualityTask("deficient", A, np.array([1.0, 2.0, 3.0]))]])
    assert result.levels[0].rank == 2 and result.levels[0].met
    np.testing.assert_allclose(A @ result.x, [1.0, 2.0, 3.0], atol=1e-12)


def test_weights_within_a_level_trade_off():
    a = EqualityTask("a", np.array([[1.0]]), np.array([0.0]), weight=3.0)
    b = EqualityTask("b", np.array([[1.0]]), np.array([1.0]), weight=1.0)
    result = HierarchicalSolver(1).solve([[a, b]])
    np.testing.assert_allclose(result.x, [0.25], atol=1e-12)  # argmin 3 x^2 + (x - 1)^2
    assert result.levels[0].task_residuals == pytest.approx({"a": 0.25, "b": 0.75})


def test_solver_is_reusable_across_ticks():
    rng = np.random.default_rng(5)
    n = 6
    solver = HierarchicalSolver(n)
    for _ in range(10):
        levels, lb, ub = random_hierarchy(rng, n, 3, bound_scale=0.3)
        np.testing.assert_allclose(solver.solve(levels, lb, ub).x, reference_hierarchy(levels, lb, ub), atol=1e-6)


@pytest.mark.parametrize(
    ("levels", "message"),
    [
        ([[]], "level 0: .*empty level"),
        ([Level((EqualityTask("a", np.eye(2), np.zeros(2)),)), Level((EqualityTask("a", np.eye(2), np.ones(2)),))],
         "task name 'a' appears twice"),
        ([[EqualityTask("a", np.eye(2), np.zeros(2)), EqualityTask("a", np.eye(2), np.zeros(2))]], "appears twice"),
        ([[EqualityTask("a", np.ones((1, 3)), np.zeros(1))]], "task 'a': 3 columns, expected n = 2"),
        ([[EqualityTask("a", np.ones((1, 2)), np.zeros(1)), EqualityTask("b", np.ones((1, 3)), np.zeros(1))]],
         "different numbers of columns"),
        ([["not a task"]], "expected EqualityTask or InequalityTask"),
    ],
)
def test_bad_levels_raise(levels, message):
    with pytest.raises(ValueError, match=message):
        HierarchicalSolver(2).solve(levels)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: EqualityTask("t", np.ones((2, 2)), np.ones(3)), r"EqualityTask 't': b must have shape \(2,\)"),
        (lambda: EqualityTask("", np.ones((2, 2)), np.ones(2)), "name must be a non-empty string"),
        (lambda: EqualityTask("t", np.ones((2, 2)), np.ones(2), weight=-1), "weight must be finite and >= 0"),
        (lambda: EqualityTask("t", np.full((1, 2), np.nan), np.ones(1)), "A has non-finite"),
        (lambda: InequalityTask("t", np.ones((1, 2)), 1.0, 0.0), "lower above upper"),
        (lambda: Level(()), "empty level"),
        (lambda: HierarchicalSolver(2, solver="osqp"), "unknown QP solver 'osqp'; valid: daqp, proxsuite"),
        (lambda: HierarchicalSolver(2, damping=-1.0), "damping must be finite and >= 0"),
        (lambda: HierarchicalSolver(2).solve([], np.ones(2), np.zeros(2)), "lower bound above upper bound"),
        (lambda: HierarchicalSolver(2).solve([], np.ones(3)), r"lower bounds must have shape \(2,\)"),
    ],
)
def test_bad_input_raises_with_a_clear_message(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_no_levels_gives_the_smallest_point_in_the_box():
    result = HierarchicalSolver(3).solve([], np.array([0.5, -2.0, -1.0]), np.array([1.0, -1.0, 1.0]))
    np.testing.assert_allclose(result.x, [0.5, -1.0, 0.0], atol=1e-9)
    assert result.ok and result.levels == ()


def _talos_like(rng: np.random.Generator, bound: float) -> tuple[list[Level], np.ndarray, np.ndarray]:
    """The IK stack's shape: 38 velocities; feet 12, CoM height 1, CoM x-y 2, waist 3, posture 32 rows."""
    levels = []
    for name, m in (("feet", 12), ("com_z", 1), ("com_xy", 2), ("waist", 3)):
        levels.append(Level((EqualityTask(name, rng.standard_normal((m, 38)), rng.standard_normal(m)),)))
    posture = np.hstack([np.zeros((32, 6)), np.eye(32)])
    levels.append(Level((EqualityTask("posture", posture, rng.standard_normal(32)),)))
    lb, ub = -bound * np.ones(38), bound * np.ones(38)
    lb[:6], ub[:6] = -np.inf, np.inf  # the floating base has no velocity bound
    return levels, lb, ub


@pytest.mark.parametrize("bound", [1e3, 0.5, 0.1])
def test_talos_sized_stack_matches_the_reference(bound):
    rng = np.random.default_rng(11)
    levels, lb, ub = _talos_like(rng, bound)
    x_ref = reference_hierarchy(levels, lb, ub)
    for solver, tol in (("daqp", 1e-6), ("proxsuite", 1e-5)):
        for fast_path in (True, False):
            result = HierarchicalSolver(38, solver=solver, fast_path=fast_path).solve(levels, lb, ub)
            if solver == "proxsuite" and not result.ok:  # reported, never silent (see ProxsuiteSolver)
                assert LevelPath.FAILED in [r.path for r in result.levels] + [result.final_path]
                continue
            assert result.ok, result.report()
            np.testing.assert_allclose(result.x, x_ref, atol=tol * _scale(x_ref), rtol=0, err_msg=solver)
            if bound == 1e3 and fast_path:
                assert all(r.path is LevelPath.NULLSPACE for r in result.levels)
    assert [r.rank for r in result.levels] == [12, 1, 2, 3, 20]


def test_deterministic_and_independent_of_history():
    """A reused solver returns bit for bit what a fresh one does, also after other problems (bounds bind)."""
    rng = np.random.default_rng(12)
    levels, lb, ub = _talos_like(rng, 0.1)
    first = HierarchicalSolver(38).solve(levels, lb, ub)
    solver = HierarchicalSolver(38)
    for _ in range(3):
        np.testing.assert_array_equal(solver.solve(levels, lb, ub).x, first.x)
        other, lb2, ub2 = _talos_like(rng, 0.2)
        solver.solve(other, lb2, ub2)


def test_level_pinned_to_a_vertex_keeps_the_point_of_the_levels_above():
    """Level 1 drives x to the corner (1, 1) of the box; level 2 has a free direction in the null space but
    the bounds leave it no room: x stays at the corner (a degenerate level QP, certified by KKT if the
    backend gives up)."""
    levels = [
        Level((EqualityTask("far", np.array([[1.0, 1.0]]), np.array([10.0])),)),
        Level((EqualityTask("diff", np.array([[1.0, -1.0]]), np.array([1.0])),)),
    ]
    for solver in ("daqp", "proxsuite"):
        result = HierarchicalSolver(2, solver=solver).solve(levels, -np.ones(2), np.ones(2))
        assert result.ok, result.report()
        np.testing.assert_allclose(result.x, [1.0, 1.0], atol=1e-9)
        assert result.levels[1].residual == pytest.approx(1.0, abs=1e-9)


def test_kkt_certificate():
    from wbcbench.qp import QPProblem
    from wbcbench.qp.hierarchical import _kkt_optimal

    # min 1/2 ||z - (1, 1)||^2 s.t. z <= 0: optimum z = 0 (gradient (-1, -1) against the active bounds)
    p = QPProblem(np.eye(2), -np.ones(2), C=np.eye(2), l=np.full(2, -np.inf), u=np.zeros(2))
    assert _kkt_optimal(p, np.zeros(2), 1e-9)
    assert not _kkt_optimal(p, np.array([-0.5, 0.0]), 1e-9)  # feasible, not optimal
    q = QPProblem(np.eye(2), np.ones(2), lb=np.zeros(2), ub=np.ones(2))  # min at the lower corner
    assert _kkt_optimal(q, np.zeros(2), 1e-9)
    assert not _kkt_optimal(q, np.array([0.0, -1.0]), 1e-9)  # infeasible


def _cascade_only(n: int) -> HierarchicalSolver:
    """The level-by-level algorithm alone (the closed-form path of equality hierarchies switched off)."""
    solver = HierarchicalSolver(n)
    solver._solve_equalities = lambda *args: None
    return solver


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), last=st.sampled_from(["none", "fills", "more"]))
def test_closed_form_matches_the_cascade(seed, last):
    """Equality hierarchies whose bounds do not bind: the closed form (one factorisation) gives the cascade's x,
    residuals, ranks and paths; the same levels solved again after their rows changed in place (as a
    controller does every tick) give the new answer."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 16))
    sizes = [int(rng.integers(1, max(2, n // 3))) for _ in range(int(rng.integers(1, 4)))]
    while sum(sizes) > n - 1:
        sizes.pop()
    if last == "fills":
        sizes.append(n - sum(sizes) + int(rng.integers(1, 4)))  # over-determined: takes all the freedom left
    elif last == "more":
        sizes += [n - sum(sizes) + 2, 2]  # ... and a level after it, locked
    sizes = [s for s in sizes if s > 0] or [1]
    buffer = rng.standard_normal((sum(sizes), n))
    rhs = rng.standard_normal(sum(sizes))
    levels, start = [], 0
    for k, m in enumerate(sizes):
        levels.append(Level((EqualityTask(f"t{k}", buffer[start:start + m], rhs[start:start + m]),), f"l{k}"))
        start += m
    levels = tuple(levels)
    lb, ub = np.full(n, -1e6), np.full(n, 1e6)
    solver, cascade = HierarchicalSolver(n), _cascade_only(n)
    for _ in range(2):
        result, reference = solver.solve(levels, lb, ub), cascade.solve(levels, lb, ub)
        assert result.ok and reference.ok
        np.testing.assert_allclose(result.x, reference.x, atol=1e-8 * _scale(reference.x), rtol=0)
        np.testing.assert_allclose([r.residual for r in result.levels], [r.residual for r in reference.levels],
                                   atol=1e-8, rtol=1e-8)
        assert [(r.rank, r.freedom, r.path, r.met) for r in result.levels] == \
            [(r.rank, r.freedom, r.path, r.met) for r in reference.levels]
        assert result.final_path is reference.final_path
        buffer += 0.1 * rng.standard_normal(buffer.shape)  # new rows, same arrays
        rhs += rng.standard_normal(rhs.shape)


def test_closed_form_leaves_binding_bounds_and_rank_deficiency_to_the_cascade():
    rng = np.random.default_rng(21)
    levels, lb, ub = _talos_like(rng, 1e3)
    free = HierarchicalSolver(38).solve(levels, lb, ub)
    np.testing.assert_allclose(free.x, _cascade_only(38).solve(levels, lb, ub).x, atol=1e-9)
    tight = 0.5 * np.abs(free.x).max()  # the unbounded answer violates these bounds
    lb2, ub2 = np.maximum(lb, -tight), np.minimum(ub, tight)
    result = HierarchicalSolver(38).solve(levels, lb2, ub2)
    np.testing.assert_allclose(result.x, _cascade_only(38).solve(levels, lb2, ub2).x, atol=1e-8)
    assert np.all(result.x <= ub2 + 1e-9) and np.all(result.x >= lb2 - 1e-9)
    # the CoM-height row repeats a foot row (rank 0 in the null space above): reported as the cascade does
    feet = levels[0].tasks[0]
    dup = Level((EqualityTask("com_z", feet.A[:1].copy(), feet.b[:1].copy()),))
    deficient = (levels[0], dup) + tuple(levels[2:])
    result = HierarchicalSolver(38).solve(deficient, lb, ub)
    reference = _cascade_only(38).solve(deficient, lb, ub)
    assert result.levels[1].rank == reference.levels[1].rank == 0
    np.testing.assert_allclose(result.x, reference.x, atol=1e-8)
