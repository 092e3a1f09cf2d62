"""The compiled stable-PD torque (`sim/spd_kernel.py`) against the same law written with numpy here."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from wbcbench.sim.simulator import Simulator
from wbcbench.types import ActuationMode, Command


def _numpy_spd(sim: Simulator) -> np.ndarray:
    m, d, b, cmd = sim.model, sim.data, sim.bridge, sim._command
    q, v = d.qpos[b.mj_q_idx], d.qvel[b.mj_v_idx]
    v_ref = cmd.v if cmd.v is not None else 0.0
    p = sim.kp * (cmd.q - q - sim.dt * v) + sim.kd * (v_ref - v)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    A = M.copy()
    A[b.mj_v_idx, b.mj_v_idx] += sim.dt * sim.kd
    rhs = -d.qfrc_bias + d.qfrc_passive + d.qfrc_constraint + d.qfrc_applied
    rhs[b.mj_v_idx] += p + (cmd.tau if cmd.tau is not None else 0.0)
    tau = p - sim.kd * sim.dt * np.linalg.solve(A, rhs)[b.mj_v_idx]
    if cmd.tau is not None:
        tau = tau + cmd.tau
    return np.clip(tau, -sim.effort, sim.effort)


@pytest.mark.parametrize("with_v, with_tau", [(False, False), (True, True)])
def test_spd_torque_matches_the_numpy_law(talos, with_v, with_tau):
    sim = Simulator(talos, mode=ActuationMode.SPD)
    rng = np.random.default_rng(int(with_v) + 2 * int(with_tau))
    q0 = sim.measure().q[7:].copy()
    worst = 0.0
    for k in range(60):
        cmd = Command(q=q0 + 0.05 * rng.normal(size=talos.na), v=0.2 * rng.normal(size=talos.na) if with_v else None,
                      tau=5.0 * rng.normal(size=talos.na) if with_tau else None)
        sim.apply(cmd)
        expected = _numpy_spd(sim)
        got = sim._spd_torque()
        worst = max(worst, float(np.abs(got - expected).max() / (1.0 + np.abs(expected).max())))
        sim.step()
    assert worst < 1e-10, worst
    # the clip is active somewhere: a large position error saturates at the effort limit
    sim.apply(Command(q=q0 + 2.0))
    assert np.any(np.isclose(np.abs(sim._spd_torque()), sim.effort))


def test_tree_solve_matches_a_dense_solve_on_branching_trees():
    """`_tree_solve` (the L^T D L factorisation along the kinematic tree) against LAPACK on random symmetric
    positive-definite matrices with a tree's sparsity: chains, branches, several roots."""
    from wbcbench.sim.spd_kernel import _tree_solve

    rng = np.random.default_rng(3)
    for trial in range(40):
        n = int(rng.integers(1, 40))
        parent = np.array([-1 if i == 0 or rng.random() < 0.1 else int(rng.integers(0, i)) for i in range(n)],
                          dtype=np.int64)
        # a joint-space inertia: sum over bodies of J_i^T m_i J_i, J_i non-zero on the body's ancestors only
        A = np.zeros((n, n))
        for i in range(n):
            chain = [i]
            while parent[chain[-1]] >= 0:
                chain.append(int(parent[chain[-1]]))
            g = np.zeros(n)
            g[chain] = rng.normal(size=len(chain))
            A += np.outer(g, g) + 0.1 * np.diag(np.isin(np.arange(n), [i]).astype(float))
        b = rng.normal(size=n)
        expected = np.linalg.solve(A, b)
        got = _tree_solve(A.copy(), parent, b)
        assert np.abs(got - expected).max() <= 1e-9 * (1.0 + np.abs(expected).max()), trial
