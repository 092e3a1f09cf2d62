"""The teleoperation stabilizer laws (paper 004 Eq. 2-7): signs, invariants on random draws, YAML parsing."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.config import Section
from wbcbench.errors import ConfigError
from wbcbench.side import Side
from wbcbench.stabilizers.teleop import (AdmittanceGains, ZmpDistributorGains, ankle_admittance, com_admittance,
                                         foot_force_difference, parse_teleop_section, wrench_admittance,
                                         zmp_distributor)

DT = 1e-3
FEET = {Side.LEFT: np.array([0.0, 0.085, 0.0]), Side.RIGHT: np.array([0.0, -0.085, 0.0])}


def test_com_admittance_moves_the_com_towards_the_measured_cop_and_leaves_z():
    g = AdmittanceGains(kd=(0.5, 0.5), kv=(1e-3, 1e-3), ka=(1e-6, 1e-6))
    p, v, a = com_admittance(np.array([0.0, 0.0, 0.9]), np.zeros(3), np.zeros(3), cop_model=np.zeros(2),
                             cop_measured=np.array([0.02, -0.01]), gains=g, dt=DT)
    np.testing.assert_allclose(p, [0.01, -0.005, 0.9])
    np.testing.assert_allclose(v, [0.02, -0.01, 0.0])          # kv e / dt
    np.testing.assert_allclose(a, [0.02, -0.01, 0.0])          # ka e / dt^2
    # a limit caps the position correction
    p, _, _ = com_admittance(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(2), np.array([1.0, 0.0]),
                             AdmittanceGains((1.0, 1.0), (0, 0), (0, 0), limit=0.03), DT)
    assert np.linalg.norm(p) == pytest.approx(0.03)


def test_ankle_admittance_lifts_the_loaded_edge():
    g = AdmittanceGains(kd=(2.0, 3.0), kv=(0, 0), ka=(0, 0))
    R = ankle_admittance(np.eye(3), np.array([0.05, 0.0]), g)      # CoP at the toes
    toe = R @ np.array([0.1, 0.0, 0.0])
    assert toe[2] > 0                                               # toes go up
    assert pin.log3(R)[1] == pytest.approx(-0.1)
    R = ankle_admittance(np.eye(3), np.array([0.0, 0.02]), g)      # CoP on the left edge
    assert (R @ np.array([0.0, 0.06, 0.0]))[2] > 0                  # left edge goes up
    assert pin.log3(R)[0] == pytest.approx(0.06)


def test_foot_force_difference_sign_unloads_the_overloaded_foot():
    g = AdmittanceGains(kd=(1e-3,), kv=(0.0,), ka=(0.0,))
    # model: equal split; measured: the left foot carries 100 N more than the right
    roll, _, _ = foot_force_difference((440.0, 440.0), (490.0, 390.0), g, DT)
    assert roll == pytest.approx(0.1)
    # a positive roll about world x moves the top of the torso towards -y, i.e. over the right foot
    assert (pin.rpy.rpyToMatrix(roll, 0, 0) @ np.array([0, 0, 1.0]))[1] < 0
    # the signed difference, not the printed absolute values: mirrored loads give the opposite correction
    roll2, _, _ = foot_force_difference((440.0, 440.0), (390.0, 490.0), g, DT)
    assert roll2 == pytest.approx(-roll)


@settings(max_examples=60, deadline=None)
@given(x=st.floats(-0.08, 0.08), y=st.floats(-0.2, 0.2), mass=st.floats(20.0, 120.0))
def test_zmp_distributor_realises_the_zmp_and_the_weight(x, y, mass):
    w, alpha = zmp_distributor(np.array([x, y]), FEET[Side.LEFT], FEET[Side.RIGHT], mass)
    assert 0.0 <= alpha <= 1.0
    fz = w[Side.LEFT][2] + w[Side.RIGHT][2]
    assert fz == pytest.approx(mass * 9.81)
    # total moment about the ZMP has no horizontal part: the ZMP of the two wrenches is the requested one
    p = np.array([x, y, 0.0])
    M = np.zeros(3)
    for s in Side:
        f = w[s][:3]
        M += w[s][3:] + np.cross(FEET[s] - p, f)
    inside = -0.085 <= y <= 0.085
    if inside:
        np.testing.assert_allclose(M[:2], 0.0, atol=1e-9 * mass * 9.81)
    # the nearer foot carries more
    if y > 0.01:
        assert w[Side.LEFT][2] > w[Side.RIGHT][2]


def test_zmp_distributor_alpha_ends():
    _, a = zmp_distributor(FEET[Side.LEFT][:2], FEET[Side.LEFT], FEET[Side.RIGHT], 90.0)
    assert a == 0.0
    _, a = zmp_distributor(FEET[Side.RIGHT][:2], FEET[Side.LEFT], FEET[Side.RIGHT], 90.0)
    assert a == 1.0


def test_wrench_admittance_eq7():
    g = ZmpDistributorGains(kp=(0.5,) * 6, kd=(0.0,) * 6)
    F, Fd = np.arange(6.0), np.zeros(6)
    np.testing.assert_allclose(wrench_admittance(F, Fd, g, DT), 0.5 * F)
    g = ZmpDistributorGains(kp=(0.0,) * 6, kd=(1e-3,) * 6)
    np.testing.assert_allclose(wrench_admittance(F, Fd, g, DT, previous_error=F - 1.0), F - 1.0)


def test_parse_section_and_errors():
    spec = parse_teleop_section(Section({
        "wrench_regularization": 1e-2,
        "stabilizer": {"cop_cutoff_hz": 20, "com_admittance": {"kd": [0.1, 0.2], "ka": 1e-7},
                       "ankle_admittance": {"enabled": False, "kd": 1.0},
                       "foot_force_difference": {"kd": 1e-4, "limit": 0.1},
                       "zmp_distributor": {"kp": 0.5, "kd": [0, 0, 1e-3, 0, 0, 0]}}}, "f.yaml", "teleop"))
    st_ = spec.stabilizer
    assert spec.wrench_regularization == 1e-2 and st_.enabled and st_.cop_cutoff_hz == 20
    assert st_.com_admittance.kd == (0.1, 0.2) and st_.com_admittance.ka == (1e-7, 1e-7)
    assert st_.ankle_admittance is None
    assert st_.foot_force_difference.limit == 0.1
    assert st_.zmp_distributor.kd[2] == 1e-3
    with pytest.raises(ConfigError, match="f.yaml.*teleop.stabilizer.com_admittance.kd"):
        parse_teleop_section(Section({"stabilizer": {"com_admittance": {"kd": [1, 2, 3]}}}, "f.yaml", "teleop"))
    with pytest.raises(ConfigError, match="unknown key"):
        parse_teleop_section(Section({"stabilizer": {"com_admitance": {}}}, "f.yaml", "teleop"))
    with pytest.raises(ConfigError, match=">= 0"):
        parse_teleop_section(Section({"stabilizer": {"com_admittance": {"kd": -1}}}, "f.yaml", "teleop"))
    # the ankle law has only a position gain (the contact task takes a pose reference)
    with pytest.raises(ConfigError, match="unknown key"):
        parse_teleop_section(Section({"stabilizer": {"ankle_admittance": {"kd": 1, "kv": 1}}}, "f.yaml", "teleop"))
