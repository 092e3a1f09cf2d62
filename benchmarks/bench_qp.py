"""Time the QP layer on random TALOS-sized problems; prints median and p99 microseconds per call.

Weighted QP (TSID-like) solves: 62 variables (38 accelerations + 24 contact-force components), 18 equalities
(6 floating-base dynamics + 12 contact accelerations), 36 inequalities (friction pyramids and unilateral
rows), cost terms of 1-32 rows (CoM 2 + 1 rows, waist 3, posture 32 on the joints, angular momentum 3, force
regularisation 24) plus Tikhonov regularisation, box bounds on the accelerations. Each tick perturbs the targets
slightly, as a control loop does, so warm starts are realistic. (The assembly of such a QP on the real robot is
the inverse-dynamics formulation's: bench_controllers.py.)

Hierarchical (IK-like): 38 variables, 5 levels of 12 (feet), 1 (CoM height), 2 (CoM x-y), 3 (waist), 32
(posture) rows, box bounds. "fast" has bounds that do not bind (null-space path on every level), "qp" is the
same problem with the fast path disabled (a QP per level), "binding" has bounds that bind (mixed paths).

Usage: ``.venv/bin/python benchmarks/bench_qp.py [--ticks N] [--seed S]``
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

from wbcbench.qp import EqualityTask, HierarchicalSolver, Level, QPProblem, make_solver, solver_names

N_WEIGHTED, N_EQ, N_IN, N_ACC = 62, 18, 36, 38
N_IK = 38
IK_LEVELS = (("feet", 12), ("com_z", 1), ("com_xy", 2), ("waist", 3), ("posture", 32))


def timed(fn: Callable[[], object], ticks: int) -> tuple[float, float]:
    """Median and p99 of ``fn`` wall time, microseconds (after 20 warm-up calls)."""
    for _ in range(20):
        fn()
    samples = np.empty(ticks)
    for i in range(ticks):
        t0 = time.perf_counter()
        fn()
        samples[i] = time.perf_counter() - t0
    samples *= 1e6
    return float(np.median(samples)), float(np.percentile(samples, 99))


def weighted_case(rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Random data shaped like one TSID tick; the equality and inequality rows share a feasible point."""
    x0 = rng.standard_normal(N_WEIGHTED)
    A_eq = rng.standard_normal((N_EQ, N_WEIGHTED))
    C = rng.standard_normal((N_IN, N_WEIGHTED))
    return {
        "x0": x0,
        "A_eq": A_eq,
        "b_eq": A_eq @ x0,
        "C": C,
        "u": C @ x0 + rng.uniform(0.05, 1.0, N_IN),
        "com": rng.standard_normal((3, N_ACC)),
        "waist": rng.standard_normal((3, N_ACC)),
        "posture": np.hstack([np.zeros((32, 6)), np.eye(32)]),
        "am": rng.standard_normal((3, N_ACC)),
        "targets": rng.standard_normal(3 + 3 + 32 + 3),
        "eye24": np.eye(24),
        "zeros24": np.zeros(24),
    }


def weighted_problem(case: dict[str, np.ndarray], t: np.ndarray) -> QPProblem:
    """One tick's QP: the cost terms summed into H and g (their assembly on a real robot is the inverse-dynamics
    formulation's, timed by bench_controllers.py), the equalities, the friction rows and box bounds."""
    H = np.zeros((N_WEIGHTED, N_WEIGHTED))
    g = np.zeros(N_WEIGHTED)
    acc = slice(0, N_ACC)
    for A, b, w in ((case["com"][:2], t[0:2], 1e3), (case["com"][2:], t[2:3], 1e3), (case["waist"], t[3:6], 1.0),
                    (case["am"], t[38:41], 2e-2), (case["posture"], t[6:38], 0.1)):
        H[acc, acc] += w * A.T @ A
        g[acc] -= w * A.T @ b
    H[N_ACC:, N_ACC:] += 1e-5 * np.eye(N_WEIGHTED - N_ACC)
    H += 1e-6 * np.eye(N_WEIGHTED)
    lb = np.full(N_WEIGHTED, -np.inf)
    ub = np.full(N_WEIGHTED, np.inf)
    lb[:N_ACC], ub[:N_ACC] = case["x0"][:N_ACC] - 50.0, case["x0"][:N_ACC] + 50.0
    return QPProblem(H, g, case["A_eq"], case["b_eq"], case["C"], np.full(N_IN, -np.inf), case["u"], lb, ub)


def bench_weighted(ticks: int, seed: int) -> list[tuple[str, float, float, str]]:
    rng = np.random.default_rng(seed)
    case = weighted_case(rng)
    noise = 0.01 * rng.standard_normal((64, case["targets"].size))
    problems = [weighted_problem(case, case["targets"] + noise[i]) for i in range(64)]
    rows = []
    for name in solver_names():
        solver = make_solver(name)
        counter = {"i": 0, "iters": []}

        def solve() -> None:
            counter["i"] += 1
            result = solver.solve(problems[counter["i"] % len(problems)])
            counter["iters"].append(result.iterations)
            if not result.ok:
                raise RuntimeError(f"{name}: {result.status}")

        med, p99 = timed(solve, ticks)
        start = "warm start" if name == "proxsuite" else "cold active set"
        x = make_solver(name).solve(problems[0]).unwrap()
        active = int(np.sum(problems[0].u - problems[0].C @ x < 1e-7))
        note = f"{start}, median iterations {np.median(counter['iters']):.0f}, {active}/36 inequality rows active"
        rows.append((f"weighted: solve {name}", med, p99, note))
    return rows


def ik_case(rng: np.random.Generator, bound: float) -> tuple[list[Level], np.ndarray, np.ndarray]:
    levels = []
    for name, m in IK_LEVELS:
        if name == "posture":
            A = np.hstack([np.zeros((32, 6)), np.eye(32)])
        else:
            A = rng.standard_normal((m, N_IK))
        levels.append(Level((EqualityTask(name, A, 0.3 * rng.standard_normal(m)),)))
    return levels, np.full(N_IK, -bound), np.full(N_IK, bound)


def bench_hierarchical(ticks: int, seed: int) -> list[tuple[str, float, float, str]]:
    rows = []
    rng = np.random.default_rng(seed)
    wide = ik_case(rng, 1e3)
    rng = np.random.default_rng(seed)
    tight = ik_case(rng, 0.15)
    cases = (("fast", wide, {}), ("qp", wide, {"fast_path": False}), ("binding", tight, {}))
    for label, (levels, lb, ub), options in cases:
        for name in solver_names():
            hqp = HierarchicalSolver(N_IK, solver=name, **options)
            result = hqp.solve(levels, lb, ub)
            paths = "/".join(r.path.value for r in result.levels)
            if label == "fast" and name != "daqp":
                continue  # the null-space path never calls the backend
            med, p99 = timed(lambda: hqp.solve(levels, lb, ub), ticks)
            tag = "" if label == "fast" else f" {name}"
            note = f"paths {paths}, final {result.final_path.value}, ok {result.ok}"
            rows.append((f"hierarchical: {label}{tag}", med, p99, note))
    return rows


def calibration(ticks: int) -> tuple[str, float, float, str]:
    """One elementary numpy call (62-vector multiply into a buffer), to compare machines."""
    a, out = np.ones(N_WEIGHTED), np.empty(N_WEIGHTED)
    med, p99 = timed(lambda: np.multiply(a, 2.0, out=out), ticks)
    return ("calibration: one numpy ufunc call", med, p99, "scale the rows by this machine's call overhead")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ticks", type=int, default=2000, help="timed calls per case (default 2000)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rows = [calibration(args.ticks)] + bench_weighted(args.ticks, args.seed) + bench_hierarchical(args.ticks, args.seed)
    width = max(len(r[0]) for r in rows)
    print(f"{'case':<{width}}  {'median us':>10}  {'p99 us':>10}  notes")
    for label, med, p99, note in rows:
        print(f"{label:<{width}}  {med:>10.1f}  {p99:>10.1f}  {note}")


if __name__ == "__main__":
    main()
