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
from wbcbench.stabilizers.base import parse_stabilizer
from wbcbench.stabilizers.teleop import (AdmittanceGains, ZmpDistributorGains, ankle_admittance, com_admittance,
                                         foot_force_difference, wrench_admittance,
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


@pytest.mark.parametrize("limit", [None, 0.02])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_torso_roll_kernel_is_the_law_bit_for_bit(seed, limit):
    """The stabilizer's compiled Eq. 4-5 and torso rotation (`_kernels.torso_roll`) give the numpy law's numbers
    exactly: roll, Rx(roll) R0, rate and acceleration (model forces floored at zero as the law's caller does)."""
    from wbcbench.stabilizers import _kernels

    rng = np.random.default_rng(seed)
    g = AdmittanceGains(kd=(3e-5,), kv=(2e-6,), ka=(1e-9,), limit=limit)
    R0 = pin.rpy.rpyToMatrix(*rng.uniform(-0.3, 0.3, 3))
    for _ in range(20):
        wl, wr = rng.normal(400, 300, 6), rng.normal(400, 300, 6)
        fl, fr = float(rng.normal(400, 300)), float(rng.normal(400, 300))
        roll, wx, ax = foot_force_difference((max(wl[2], 0.0), max(wr[2], 0.0)), (fl, fr), g, DT)
        c, s = np.cos(roll), np.sin(roll)
        R_law = np.array([R0[0], c * R0[1] - s * R0[2], s * R0[1] + c * R0[2]])
        R, w, a = np.empty((3, 3)), np.empty(6), np.empty(6)
        got = _kernels.torso_roll(wl, wr, fl, fr, g.kd[0], g.kv[0], g.ka[0], np.nan if limit is None else limit, DT,
                                  R0, R, w, a)
        assert got == roll
        np.testing.assert_array_equal(R, R_law)
        np.testing.assert_array_equal(w, [0, 0, 0, wx, 0, 0])
        np.testing.assert_array_equal(a, [0, 0, 0, ax, 0, 0])


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
    spec = parse_stabilizer(Section({
        "type": "force", "cop_cutoff_hz": 20, "com_admittance": {"kd": [0.1, 0.2], "ka": 1e-7},
        "ankle_admittance": {"enabled": False, "kd": 1.0},
        "foot_force_difference": {"kd": 1e-4, "limit": 0.1},
        "zmp_distributor": {"kp": 0.5, "kd": [0, 0, 1e-3, 0, 0, 0]}}, "f.yaml", "stabilizer"))
    st_ = spec.spec
    assert spec.type == "force" and st_.enabled and st_.cop_cutoff_hz == 20
    assert st_.com_admittance.kd == (0.1, 0.2) and st_.com_admittance.ka == (1e-7, 1e-7)
    assert st_.ankle_admittance is None
    assert st_.foot_force_difference.limit == 0.1
    assert st_.zmp_distributor.kd[2] == 1e-3

    def parse(data):
        return parse_stabilizer(Section({"type": "force", **data}, "f.yaml", "stabilizer"))

    with pytest.raises(ConfigError, match="f.yaml.*stabilizer.com_admittance.kd"):
        parse({"com_admittance": {"kd": [1, 2, 3]}})
    with pytest.raises(ConfigError, match="unknown key"):
        parse({"com_admitance": {}})
    with pytest.raises(ConfigError, match=">= 0"):
        parse({"com_admittance": {"kd": -1}})
    # the ankle law has only a position gain (the contact task takes a pose reference)
    with pytest.raises(ConfigError, match="unknown key"):
        parse({"ankle_admittance": {"kd": 1, "kv": 1}})
    with pytest.raises(ConfigError, match="unknown stabilizer type 'forse'.*did you mean 'force'"):
        parse_stabilizer(Section({"type": "forse"}, "f.yaml", "stabilizer"))


# ---- the per-tick measurement and the reference split ------------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_measured_wrench_is_contact_wrench_from_ft(seed):
    from wbcbench.estimation import FootMass, contact_wrench_from_ft
    from wbcbench.stabilizers.teleop import measured_wrench

    rng = np.random.default_rng(seed)
    f, m = rng.normal(scale=300.0, size=3), rng.normal(scale=30.0, size=3)
    R, p = pin.exp3(rng.normal(scale=0.3, size=3)), rng.normal(size=3)
    foot = FootMass(1.6, rng.normal(scale=0.05, size=3))
    ref = contact_wrench_from_ft(f, m, R, p, foot)
    F, M = measured_wrench(f, m, R, p, foot.mass, np.array(foot.p_sensor_com))
    np.testing.assert_allclose(F, ref.force, atol=1e-10)
    np.testing.assert_allclose(M, ref.moment, atol=1e-10)


def test_stabilizer_measurement_matches_the_estimation_functions(talos):
    """The stabilizer's per-tick CoPs and ZMP (no validation, scalar arithmetic) are the estimation module's."""
    from wbcbench.estimation import center_of_pressure, contact_wrench_from_ft, zmp_from_wrenches
    from wbcbench.sim.simulator import Simulator
    from wbcbench.stabilizers.teleop import TeleopStabilizer, TeleopStabilizerSpec
    from wbcbench.types import Command

    sim = Simulator(talos, mode="spd")
    q = talos.q0.copy()
    sim.reset(q)
    upper = np.array([n.startswith(("torso", "arm")) for n in talos.joint_names])
    for _ in range(50):  # settle with the upper body leaning and the arms out, so that the CoPs are off centre
        sim.apply(Command(q=q[7:] + 0.2 * upper * np.sin(np.arange(talos.na)), v=np.zeros(talos.na)))
        sim.step(1)
    meas = sim.measure()
    stab = TeleopStabilizer(talos, TeleopStabilizerSpec(min_normal_force=10.0), DT)
    stab._measure(meas)
    got = stab.measured
    m, d = talos.model, talos.model.createData()
    pin.framesForwardKinematics(m, d, meas.q)
    wrenches, ground = [], []
    for s in Side:
        M = d.oMf[m.getFrameId(talos.profile.feet[s].ft_sensor_frame)]
        w = contact_wrench_from_ft(meas.ft_force[s], meas.ft_torque[s], M.rotation, M.translation, stab.feet[s])
        wrenches.append(w)
        S = d.oMf[talos.sole_frame_id(s)]
        ground.append(S.translation[2])
        cop = center_of_pressure(w, float(S.translation[2]))
        local = S.rotation.T @ (cop.point - S.translation)
        np.testing.assert_allclose(got.cop_sole[s], local[:2], atol=1e-9)
        assert got.normal_force[s] == pytest.approx(float(w.force[2]))
    np.testing.assert_allclose(got.zmp, zmp_from_wrenches(wrenches, min(ground))[:2], atol=1e-9)
    assert np.abs(got.zmp).max() > 1e-3


def test_reference_targets_carry_the_weight_at_the_reference_zmp():
    """F of Eq. 7 (the QP's wrench targets without the distributor): the weight, split at the cart-table ZMP of
    the CoM reference, in the QP's variables (LOCAL sole frame, about the sole origin)."""
    from wbcbench.stabilizers.teleop import reference_wrench_targets

    yaw = 0.2
    feet = {s: pin.SE3(pin.rpy.rpyToMatrix(0, 0, yaw), FEET[s] + np.array([0.01, 0.0, 0.002])) for s in Side}
    com, acc, mass = np.array([0.02, 0.03, 0.88]), np.array([0.1, -0.2, 0.0]), 90.0
    W = reference_wrench_targets(com, acc, feet, np.zeros(3), mass)
    f_tot, m_tot = np.zeros(3), np.zeros(3)
    for s in Side:
        f = feet[s].rotation @ W[s][:3]
        f_tot += f
        m_tot += feet[s].rotation @ W[s][3:] + np.cross(feet[s].translation, f)
    np.testing.assert_allclose(f_tot, [0, 0, mass * 9.81], atol=1e-9)
    ground = 0.002
    zmp = com[:2] - (com[2] - ground) / 9.81 * acc[:2]
    m_at = m_tot + np.cross(np.array([0.0, 0.0, 0.0]) - np.array([zmp[0], zmp[1], ground]), f_tot)
    np.testing.assert_allclose(m_at[:2], 0.0, atol=1e-9)
    one = reference_wrench_targets(com, acc, {Side.LEFT: feet[Side.LEFT]}, np.zeros(3), mass)
    np.testing.assert_allclose(feet[Side.LEFT].rotation @ one[Side.LEFT][:3], [0, 0, mass * 9.81], atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_reference_split_kernel_matches_the_laws(seed):
    """The compiled split (`_kernels.reference_split`) is `zmp_distributor` on `_cart_table_zmp`, then
    `split_to_local`, on tilted and yawed feet with an off-centre sole."""
    from wbcbench.stabilizers._kernels import reference_split
    from wbcbench.stabilizers.teleop import _cart_table_zmp, split_to_local, zmp_distributor

    rng = np.random.default_rng(seed)
    feet = {s: pin.SE3(pin.rpy.rpyToMatrix(*rng.uniform(-0.1, 0.1, 2), rng.uniform(-0.5, 0.5)),
                       FEET[s] + rng.uniform(-0.02, 0.02, 3)) for s in Side}
    sole_center = np.array([0.012, -0.004, 0.0])
    com, acc, mass = rng.uniform([-0.1, -0.1, 0.8], [0.1, 0.1, 0.9]), rng.uniform(-2, 2, 3), 93.0
    centres = {s: M.act(sole_center) for s, M in feet.items()}
    F, alpha = zmp_distributor(_cart_table_zmp(com, acc, centres), centres[Side.LEFT], centres[Side.RIGHT], mass)
    expected = split_to_local(F, feet, centres)
    out = np.empty((2, 6))
    got_alpha = reference_split(com, acc, feet[Side.LEFT].rotation, feet[Side.LEFT].translation,
                                feet[Side.RIGHT].rotation, feet[Side.RIGHT].translation, sole_center, mass, 9.81, out)
    assert got_alpha == pytest.approx(alpha, abs=1e-12)
    for i, s in enumerate(Side):
        np.testing.assert_allclose(out[i], expected[s], rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_feet_measurement_kernel_matches_the_laws(seed):
    """The compiled measurement (`_kernels.feet_measurement`) is `measured_wrench` and the moment about the sole
    height / the ground per foot: normal forces, CoPs in the sole frame from its centre, the ZMP; a foot below
    the threshold has no CoP and is left out of the ZMP."""
    from wbcbench.stabilizers._kernels import feet_measurement
    from wbcbench.stabilizers.teleop import _moment_about, measured_wrench

    rng = np.random.default_rng(seed)
    R_s = np.array([pin.rpy.rpyToMatrix(*rng.uniform(-0.2, 0.2, 3)) for _ in Side])
    p_s = rng.uniform([-0.1, -0.2, 0.08], [0.1, 0.2, 0.12], (2, 3))
    f_s = np.array([[rng.normal(0, 20), rng.normal(0, 20), -rng.uniform(300, 600)], [1.0, -2.0, 10.0 + 3.0 * seed]])
    m_s = rng.normal(0, 10, (2, 3))
    mass, com = np.array([1.4, 1.5]), rng.uniform(-0.02, 0.02, (2, 3))
    R_sole = np.array([pin.rpy.rpyToMatrix(*rng.uniform(-0.1, 0.1, 3)) for _ in Side])
    p_sole = p_s - [0.0, 0.0, 0.1] + rng.uniform(-0.01, 0.01, (2, 3))
    centre, thr = np.array([0.01, -0.003, 0.0]), 10.0
    out, zmp = np.empty((2, 4)), np.empty(2)
    assert feet_measurement(R_s, p_s, f_s, m_s, mass, com, R_sole, p_sole, centre, thr, 9.81, out, zmp)
    ground = p_sole[:, 2].min()
    tot = np.zeros(3)
    for i in range(2):
        F, M = measured_wrench(f_s[i], m_s[i], R_s[i], p_s[i], mass[i], com[i])
        assert out[i, 0] == pytest.approx(F[2], rel=1e-12)
        if F[2] >= thr:
            mx, my = _moment_about(F, M, p_s[i], p_sole[i, 2])
            local = R_sole[i].T @ (np.array([-my / F[2], mx / F[2], p_sole[i, 2]]) - p_sole[i])
            np.testing.assert_allclose(out[i, 1:3], local[:2] - centre[:2], rtol=1e-10, atol=1e-12)
            tot += [F[2], *_moment_about(F, M, p_s[i], ground)]
        else:
            assert np.isnan(out[i, 1:3]).all() and out[i, 3] == 0.0
    assert out[0, 3] == 1.0 and out[1, 3] == 0.0
    np.testing.assert_allclose(zmp, [-tot[2] / tot[0], tot[1] / tot[0]], rtol=1e-10, atol=1e-12)


def test_measurement_filters():
    """`_kernels.filter_measurement`: the first input is taken as it is, then y += alpha (u - y); the normal
    forces are clipped at 0 and filtered every tick, a CoP only while its foot is loaded, the ZMP while it exists;
    a non-finite input is skipped, a non-finite state restarts from the input."""
    from wbcbench.stabilizers._kernels import filter_measurement
    from wbcbench.stabilizers.teleop import low_pass_gain

    a = low_pass_gain(20.0, 1e-3)
    assert a == pytest.approx(1 - np.exp(-2 * np.pi * 0.02)) and low_pass_gain(None, 1e-3) == 1.0
    state, started = np.zeros(8), np.zeros(5, dtype=bool)
    nan = np.nan
    raw = np.array([[400.0, 0.01, -0.02, 1.0], [-5.0, nan, nan, 0.0]])
    filter_measurement(raw, np.array([0.1, 0.2]), True, a, state, started)
    np.testing.assert_array_equal(state, [0.1, 0.2, 0.01, -0.02, 0.0, 0.0, 400.0, 0.0])
    np.testing.assert_array_equal(started, [True, True, False, True, True])
    raw = np.array([[500.0, 0.03, nan, 1.0], [300.0, 0.05, 0.06, 1.0]])
    filter_measurement(raw, np.array([nan, 0.0]), False, a, state, started)
    np.testing.assert_allclose(state, [0.1, 0.2, 0.01, -0.02, 0.05, 0.06, 400.0 + a * 100.0, a * 300.0])
    state[0] = np.inf  # a non-finite state restarts from the next input
    filter_measurement(raw, np.array([0.3, 0.4]), True, a, state, started)
    np.testing.assert_allclose(state[:2], [0.3, 0.4])
    np.testing.assert_allclose(state[4:6], [0.05 + a * 0.0, 0.06 + a * 0.0])
