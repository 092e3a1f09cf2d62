"""E_m, E_m+, costs of transport (Eq. 10) on signals with known answers."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from wbcbench.metrics import (
    MechanicalEnergy,
    cost_of_transport,
    horizontal_distance,
    joint_power,
    mechanical_energy,
)


def test_constant_power_gives_p_times_t():
    n, dt = 1000, 1e-3
    tau, omega = np.full(n, 2.0), np.full(n, 3.0)  # P = 6 W over T = 1 s
    e = mechanical_energy(tau, omega, dt)
    assert e.e_m == pytest.approx(6.0, rel=1e-12)
    assert e.e_m_plus == pytest.approx(6.0, rel=1e-12)
    assert e.duration == pytest.approx(1.0, rel=1e-12)


def test_negative_power_counts_in_e_m_only():
    n, dt = 500, 2e-3
    e = mechanical_energy(np.full(n, 2.0), np.full(n, -3.0), dt)
    assert e.e_m == pytest.approx(6.0, rel=1e-12)
    assert e.e_m_plus == 0.0


def test_positive_part_is_per_joint():
    # Joint 0 gives +6 W, joint 1 absorbs 6 W: the sum is 0 but Eq. 10 keeps q_0 > 0.
    n, dt = 100, 1e-2
    tau = np.tile([2.0, 2.0], (n, 1))
    omega = np.tile([3.0, -3.0], (n, 1))
    e = mechanical_energy(tau, omega, dt)
    assert e.e_m == pytest.approx(12.0)
    assert e.e_m_plus == pytest.approx(6.0)
    np.testing.assert_allclose(joint_power(tau, omega)[0], [6.0, -6.0])


def test_sinusoid_over_one_period():
    # q = sin t cos t = sin(2t) / 2: int |q| over [0, 2 pi) = 2, positive half = 1.
    n = 200_000
    dt = 2 * np.pi / n
    t = np.arange(n) * dt
    e = mechanical_energy(np.sin(t), np.cos(t), dt)
    assert e.e_m == pytest.approx(2.0, rel=1e-6)
    assert e.e_m_plus == pytest.approx(1.0, rel=1e-6)


def test_per_tick_durations():
    e = mechanical_energy([1.0, 1.0, 1.0], [1.0, -2.0, 4.0], dt=[0.5, 0.25, 0.25])
    assert e.e_m == pytest.approx(0.5 + 0.5 + 1.0)
    assert e.e_m_plus == pytest.approx(0.5 + 1.0)
    assert e.duration == pytest.approx(1.0)


def test_cost_of_transport_and_the_published_table():
    e = MechanicalEnergy(e_m=981.0, e_m_plus=490.5, duration=10.0)
    cot = cost_of_transport(e, mass=100.0, distance=2.0)
    assert cot.c_et == pytest.approx(0.5) and cot.c_mt == pytest.approx(0.25)
    # Table 6, IK 20 cm: E_m 1983.9 J, E_m+ 1359.3 J -> C_et 1.68, C_mt 1.15 with m g = 981 N, D = 1.2 m.
    cot = cost_of_transport(MechanicalEnergy(1983.9, 1359.3, 8.0), mass=100.0, distance=1.2)
    assert round(cot.c_et, 2) in (1.68, 1.69) and round(cot.c_mt, 2) == 1.15


def test_horizontal_distance_ignores_height():
    stairs = np.array([[0.0, 0.0, 1.0], [0.9, 0.05, 1.3], [1.8, 0.0, 1.6]])
    assert horizontal_distance(stairs) == pytest.approx(1.8)
    assert horizontal_distance([[0.0, 0.0], [3.0, 4.0]]) == pytest.approx(5.0)


@pytest.mark.parametrize(
    ("tau", "omega", "dt", "match"),
    [
        (np.ones(5), np.ones(4), 1e-3, "mismatched lengths"),
        (np.ones((5, 2)), np.ones((5, 3)), 1e-3, "shape"),
        (np.array([1.0, np.nan]), np.ones(2), 1e-3, "non-finite"),
        (np.ones(3), np.array([1.0, np.inf, 0.0]), 1e-3, "non-finite"),
        (np.zeros(0), np.zeros(0), 1e-3, "empty"),
        (np.ones(3), np.ones(3), 0.0, "dt"),
        (np.ones(3), np.ones(3), np.ones(2), "dt"),
        (np.ones((2, 2, 2)), np.ones((2, 2, 2)), 1e-3, "shape"),
    ],
)
def test_energy_bad_input(tau, omega, dt, match):
    with pytest.raises(ValueError, match=match):
        mechanical_energy(tau, omega, dt)


def test_cost_of_transport_bad_input():
    e = MechanicalEnergy(1.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="distance"):
        cost_of_transport(e, mass=90.0, distance=0.0)
    with pytest.raises(ValueError, match="mass"):
        cost_of_transport(e, mass=float("nan"), distance=1.0)
    with pytest.raises(ValueError, match="MechanicalEnergy"):
        cost_of_transport((1.0, 1.0), mass=90.0, distance=1.0)
    with pytest.raises(ValueError, match="base_positions"):
        horizontal_distance(np.zeros(3))


_finite = st.floats(-100.0, 100.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 20).flatmap(lambda n: st.tuples(arrays(float, (n, 3), elements=_finite),
                                                      arrays(float, (n, 3), elements=_finite))))
def test_energy_invariants(signals):
    tau, omega = signals
    dt = 1e-3
    e = mechanical_energy(tau, omega, dt)
    q = tau * omega
    assert e.e_m >= e.e_m_plus >= 0.0
    # E_m = E_m+ + |E_m-|, and the per-joint positive part bounds the positive part of the sum.
    assert e.e_m == pytest.approx(e.e_m_plus + dt * np.clip(-q, 0, None).sum(), abs=1e-9)
    assert e.e_m_plus >= dt * np.clip(q.sum(axis=1), 0, None).sum() - 1e-9
