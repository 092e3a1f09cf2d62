"""DCM PI controller and CoM admittance (paper 000 Eq. 2-4): identities, signs, integral, filter, closed loop."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.planning import PatternGeneratorConfig, SoleRectangle, StepTiming, generate_walk, straight_walk
from wbcbench.stabilizers import (
    IK_GAINS,
    IK_STAIRS_GAINS,
    PAPER_GAINS,
    TSID_POSITION_GAINS,
    DcmGains,
    DcmStabilizer,
    FirstOrderLowPass,
    com_admittance,
    dcm_from_com,
    dcm_pi_zmp,
    natural_frequency,
)

DT = 1e-3
COM_HEIGHT = 0.87
OMEGA = np.sqrt(9.81 / COM_HEIGHT)
C_REF = np.array([0.1, -0.02, COM_HEIGHT])
ZERO3 = np.zeros(3)


def stab(**gains):
    return DcmStabilizer(dataclasses.replace(IK_GAINS, **gains), dt=DT, com_height=COM_HEIGHT)


def test_paper_gain_sets():
    assert (IK_GAINS.kp_adm, IK_GAINS.kp_dcm, IK_GAINS.ki_dcm, IK_GAINS.kz_dcm) == (15.0, 8.0, 1.0, 1.0)
    assert DcmGains() == IK_GAINS
    assert (TSID_POSITION_GAINS.kp_adm, TSID_POSITION_GAINS.kp_dcm, TSID_POSITION_GAINS.ki_dcm,
            TSID_POSITION_GAINS.kz_dcm) == (12.0, 8.0, 1.0, 1.0)
    assert (IK_STAIRS_GAINS.kp_adm, IK_STAIRS_GAINS.kp_dcm) == (45.0, 25.0)
    assert set(PAPER_GAINS) == {"ik", "ik_stairs", "tsid_position"}
    assert IK_GAINS.zmp_cutoff_hz is None  # low-pass off by default
    with pytest.raises(dataclasses.FrozenInstanceError):
        IK_GAINS.kp_adm = 1.0  # type: ignore[misc]


@pytest.mark.parametrize("kwargs, match", [
    ({"kp_adm": -1.0}, "kp_adm"), ({"ki_dcm": float("nan")}, "ki_dcm"), ({"integral_limit": 0.0}, "integral_limit"),
    ({"zmp_cutoff_hz": -5.0}, "zmp_cutoff_hz"), ({"com_offset_limit": 0.0}, "com_offset_limit"),
])
def test_gains_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        DcmGains(**kwargs)


def test_laws_by_hand():
    assert natural_frequency(COM_HEIGHT) == pytest.approx(OMEGA)
    np.testing.assert_allclose(dcm_from_com([1.0, 2.0], [0.3, -0.6], 3.0), [1.1, 1.8])
    # Eq. 3 with every term active.
    z_star = dcm_pi_zmp(p_zmp_ref=[0.0], dcm_ref=[0.1], dcm_measured=[0.05], p_zmp_measured=[0.02],
                        dcm_error_integral=[0.2], omega=4.0, kp_dcm=8.0, ki_dcm=1.0, kz_dcm=2.0)
    expected = 0.0 - (1 + 8 / 4) * 0.05 + (2 / 4) * (0.0 - 0.02) - (1 / 4) * 0.2
    np.testing.assert_allclose(z_star, [expected])
    # Eq. 4.
    np.testing.assert_allclose(com_admittance([0.5], [0.03], [0.01], 15.0), [0.5 + 15 * 0.02])


def test_zero_error_passes_the_reference_through():
    plan = straight_walk(2, 0.2, foot_separation=0.1714, sole=SoleRectangle(0.2, 0.13),
                         timing=StepTiming(0.9, 0.115, final_double_support=1.0))
    walk = generate_walk(plan, PatternGeneratorConfig(com_height=COM_HEIGHT))
    s = DcmStabilizer(IK_GAINS, dt=walk.dt, com_height=COM_HEIGHT)
    for k in range(2000, walk.n_ticks, 7):  # walking part
        c, v, a, z = walk.p_world_com[k], walk.v_world_com[k], walk.a_world_com[k], walk.p_world_zmp_ref[k]
        out = s.step(p_com_ref=c, v_com_ref=v, a_com_ref=a, p_zmp_ref=z, p_com=c, v_com=v, p_zmp=z)
        np.testing.assert_array_equal(out.p_world_com, c)
        np.testing.assert_array_equal(out.v_world_com, v)
        np.testing.assert_array_equal(out.a_world_com, a)
        np.testing.assert_array_equal(out.p_world_zmp_desired, z[:2])
        np.testing.assert_array_equal(out.dcm_error_integral, 0.0)
        np.testing.assert_allclose(out.p_world_dcm_ref, walk.p_world_dcm[k, :2], atol=1e-15)


@settings(max_examples=50, deadline=None)
@given(ex=st.floats(-0.05, 0.05), ey=st.floats(-0.05, 0.05))
def test_corrected_zmp_pushes_the_dcm_back(ex, ey):
    """A DCM behind its reference moves the desired ZMP so that xi_dot = omega (xi - z*) reduces the error,
    and the admittance accelerates the CoM towards the reference."""
    error = np.array([ex, ey])
    if np.linalg.norm(error) < 1e-6:
        return
    s = stab()
    z_ref = C_REF[:2]
    # Measured CoM displaced by -error: xi_ref - xi = error.
    out = s.step(p_com_ref=C_REF, v_com_ref=ZERO3, a_com_ref=ZERO3, p_zmp_ref=z_ref,
                 p_com=C_REF[:2] - error, v_com=np.zeros(2), p_zmp=z_ref)
    shift = out.p_world_zmp_desired - z_ref
    assert shift @ error < 0.0  # the ZMP goes opposite to the error...
    np.testing.assert_allclose(shift, -(1 + IK_GAINS.kp_dcm / OMEGA) * error, atol=1e-15)
    # ... so the error e = xi_ref - xi obeys e_dot = -kp_dcm e under ideal ZMP tracking.
    xi, xi_ref = out.p_world_dcm, out.p_world_dcm_ref
    e_dot = OMEGA * (xi_ref - z_ref) - OMEGA * (xi - out.p_world_zmp_desired)
    np.testing.assert_allclose(e_dot, -IK_GAINS.kp_dcm * error, atol=1e-12)
    # Admittance: the measured ZMP is beyond z* in the error's direction, so the CoM accelerates along it.
    assert out.a_world_com[:2] @ error > 0.0


def test_zmp_feedback_sign():
    """kz term: a measured ZMP ahead of the reference moves z* ahead too (Eq. 3), and the admittance then
    accelerates the CoM only by the remaining difference."""
    s = stab()
    z_ref = np.array([0.0, 0.0])
    out = s.step(p_com_ref=np.r_[0.0, 0.0, COM_HEIGHT], v_com_ref=ZERO3, a_com_ref=ZERO3, p_zmp_ref=z_ref,
                 p_com=np.zeros(2), v_com=np.zeros(2), p_zmp=np.array([0.02, 0.0]))
    assert out.p_world_zmp_desired[0] == pytest.approx(-(IK_GAINS.kz_dcm / OMEGA) * 0.02)
    assert out.a_world_com[0] == pytest.approx(IK_GAINS.kp_adm * (0.02 - out.p_world_zmp_desired[0]))


def test_ideal_zmp_tracking_recovers_a_dcm_error():
    """Closed loop on the LIPM with the ZMP following z* one tick late: a 3 cm DCM error vanishes."""
    for gains in (IK_GAINS, TSID_POSITION_GAINS, IK_STAIRS_GAINS):
        s = DcmStabilizer(gains, dt=DT, com_height=COM_HEIGHT)
        c, v = np.array([0.03, -0.02]), np.zeros(2)
        z = np.zeros(2)
        for _ in range(3000):
            out = s.step(p_com_ref=np.r_[0.0, 0.0, COM_HEIGHT], v_com_ref=ZERO3, a_com_ref=ZERO3,
                         p_zmp_ref=np.zeros(2), p_com=c, v_com=v, p_zmp=z)
            a = OMEGA**2 * (c - z)
            c, v = c + v * DT + 0.5 * a * DT**2, v + a * DT
            z = out.p_world_zmp_desired
        assert np.linalg.norm(dcm_from_com(c, v, OMEGA)) < 1e-3
        assert np.linalg.norm(c) < 5e-3


def test_integral_winds_up_and_is_clamped():
    s = stab(integral_limit=0.02)
    error = np.array([0.01, -0.003])
    kwargs = dict(p_com_ref=C_REF, v_com_ref=ZERO3, a_com_ref=ZERO3, p_zmp_ref=C_REF[:2], p_com=C_REF[:2] - error,
                  v_com=np.zeros(2), p_zmp=C_REF[:2])
    for _ in range(1000):
        out = s.step(**kwargs)
    np.testing.assert_allclose(out.dcm_error_integral, error * 1.0, rtol=1e-9)  # 1 s of a constant error
    assert not out.integral_saturated.any()
    # The integral term enters z* of the next tick with -(ki / omega).
    nxt = s.step(**kwargs)
    np.testing.assert_allclose(nxt.p_world_zmp_desired,
                               C_REF[:2] - (1 + 8.0 / OMEGA) * error - (1.0 / OMEGA) * error * 1.0, rtol=1e-6)
    for _ in range(3000):
        out = s.step(**kwargs)
    np.testing.assert_allclose(out.dcm_error_integral, [0.02, -0.003 * 4.001], rtol=1e-9)  # x clamped, y winding
    assert out.integral_saturated.tolist() == [True, False]
    s.reset()
    np.testing.assert_array_equal(s.dcm_error_integral, 0.0)
    np.testing.assert_array_equal(s.com_offset, 0.0)


def test_integral_leak_bounds_the_integral():
    s = stab(integral_limit=None, integral_leak=2.0)
    error = np.array([0.01, 0.0])
    for _ in range(10000):
        out = s.step(p_com_ref=C_REF, v_com_ref=ZERO3, a_com_ref=ZERO3, p_zmp_ref=C_REF[:2],
                     p_com=C_REF[:2] - error, v_com=np.zeros(2), p_zmp=C_REF[:2])
    np.testing.assert_allclose(out.dcm_error_integral, error / 2.0, rtol=1e-3)


def test_admittance_integrates_into_the_com_reference():
    """A constant ZMP error gives a constant extra acceleration, integrated twice into the CoM offset."""
    s = stab(kp_dcm=0.0, ki_dcm=0.0, kz_dcm=0.0)
    dz = np.array([0.01, 0.0])
    n = 500
    for _ in range(n):
        out = s.step(p_com_ref=C_REF, v_com_ref=ZERO3, a_com_ref=ZERO3, p_zmp_ref=C_REF[:2], p_com=C_REF[:2],
                     v_com=np.zeros(2), p_zmp=C_REF[:2] + dz)
    a = IK_GAINS.kp_adm * dz
    T = n * DT
    np.testing.assert_allclose(out.a_world_com[:2], a)
    np.testing.assert_allclose(out.v_world_com[:2], a * T, rtol=1e-12)
    np.testing.assert_allclose(out.p_world_com[:2] - C_REF[:2], 0.5 * a * T**2, rtol=1e-12)
    assert out.p_world_com[2] == C_REF[2]


def test_com_offset_clamp():
    s = stab(kp_dcm=0.0, ki_dcm=0.0, kz_dcm=0.0, com_offset_limit=0.03)
    for _ in range(3000):
        out = s.step(p_com_ref=C_REF, v_com_ref=ZERO3, a_com_ref=ZERO3, p_zmp_ref=C_REF[:2], p_com=C_REF[:2],
                     v_com=np.zeros(2), p_zmp=C_REF[:2] + [0.05, -0.05])
    np.testing.assert_allclose(out.p_world_com[:2] - C_REF[:2], [0.03, -0.03])
    np.testing.assert_allclose(out.v_world_com[:2], 0.0)


def test_zmp_low_pass():
    f = FirstOrderLowPass(20.0, DT)
    assert f(np.array([1.0])) == pytest.approx(1.0)  # first sample initialises
    f.reset()
    f(np.zeros(1))
    tau = 1.0 / (2 * np.pi * 20.0)
    n = int(round(tau / DT))
    for _ in range(n):
        y = f(np.ones(1))
    assert y[0] == pytest.approx(1.0 - np.exp(-n * DT / tau), rel=1e-9)
    # In the stabilizer: a ZMP step is seen filtered.
    s = stab(zmp_cutoff_hz=20.0)
    base = dict(p_com_ref=C_REF, v_com_ref=ZERO3, a_com_ref=ZERO3, p_zmp_ref=C_REF[:2], p_com=C_REF[:2],
                v_com=np.zeros(2))
    s.step(**base, p_zmp=C_REF[:2])
    out = s.step(**base, p_zmp=C_REF[:2] + [0.1, 0.0])
    assert out.p_world_zmp_measured[0] - C_REF[0] == pytest.approx(0.1 * f.alpha)
    unfiltered = stab().step(**base, p_zmp=C_REF[:2] + [0.1, 0.0])
    assert unfiltered.p_world_zmp_measured[0] - C_REF[0] == pytest.approx(0.1)


def test_input_validation():
    s = stab()
    with pytest.raises(ValueError, match="p_com_ref"):
        s.step(p_com_ref=np.zeros(2), v_com_ref=ZERO3, a_com_ref=ZERO3, p_zmp_ref=np.zeros(2), p_com=np.zeros(2),
               v_com=np.zeros(2), p_zmp=np.zeros(2))
    with pytest.raises(ValueError, match="p_zmp"):
        s.step(p_com_ref=ZERO3, v_com_ref=ZERO3, a_com_ref=ZERO3, p_zmp_ref=np.zeros(2), p_com=np.zeros(2),
               v_com=np.zeros(2), p_zmp=np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="com_height"):
        DcmStabilizer(IK_GAINS, dt=DT, com_height=0.0)
    with pytest.raises(ValueError, match="gains"):
        DcmStabilizer({"kp_adm": 15}, dt=DT, com_height=COM_HEIGHT)  # type: ignore[arg-type]


@pytest.mark.parametrize("gains", [DcmGains(), DcmGains(zmp_cutoff_hz=20.0, com_offset_limit=0.01,
                                                        integral_limit=0.002, integral_leak=0.5)])
def test_compiled_step_is_the_numpy_step(gains):
    """float64 vectors take the compiled step: the same numbers, bit for bit, as the validated numpy step, with
    the filter, the offset clamp, the leak and the anti-windup switched on, and in a mixed sequence of both."""
    rng = np.random.default_rng(1)
    fast = DcmStabilizer(gains, dt=1e-3, com_height=0.87)
    slow = DcmStabilizer(gains, dt=1e-3, com_height=0.87)
    for k in range(2000):
        args = [rng.standard_normal(3) * s for s in (0.1, 0.1, 1.0, 0.1, 0.1, 0.1, 0.1)]
        if k % 3 == 0:
            args[3] = args[3][:2]  # a (2,) ZMP
        a = fast.step(**dict(zip(("p_com_ref", "v_com_ref", "a_com_ref", "p_zmp_ref", "p_com", "v_com", "p_zmp"),
                                 args)))
        b = slow._step_numpy(*args)
        if k % 11 == 0:  # the other path on the other object now and then: one state
            fast, slow = slow, fast
        for name in ("p_world_com", "v_world_com", "a_world_com", "p_world_zmp_desired", "p_world_zmp_measured",
                     "p_world_dcm", "p_world_dcm_ref", "dcm_error_integral", "integral_saturated"):
            x, y = getattr(a, name), getattr(b, name)
            assert x.shape == y.shape and x.dtype == y.dtype
            np.testing.assert_array_equal(x, y, err_msg=f"{name} at tick {k}")
