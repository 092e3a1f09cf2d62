"""Gait-stage split and the passivity gait measure (Eq. 11-12)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from wbcbench.metrics import GaitSegment, GaitStage, passivity_gait_measure, split_gait_stages, torque_rms

# Columns: 0-1 left ankle, 2-3 right ankle, 4 a knee.
LEFT, RIGHT = [0, 1], [2, 3]


def schedule():
    """DS 3 ticks, left support 4, DS 2, right support 4, DS 3 (16 ticks)."""
    left = np.array([1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 1, 1, 1], dtype=bool)
    right = np.array([1, 1, 1, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1], dtype=bool)
    return left, right


def test_split_matches_a_hand_built_schedule():
    left, right = schedule()
    assert split_gait_stages(left, right) == [
        GaitSegment(GaitStage.DOUBLE_SUPPORT, 0, 3),
        GaitSegment(GaitStage.LEFT_SUPPORT, 3, 7),
        GaitSegment(GaitStage.DOUBLE_SUPPORT, 7, 9),
        GaitSegment(GaitStage.RIGHT_SUPPORT, 9, 13),
        GaitSegment(GaitStage.DOUBLE_SUPPORT, 13, 16),
    ]


def test_split_flight_and_integer_flags():
    segs = split_gait_stages([1, 0, 0, 0], [1, 1, 0, 0])
    assert [(s.stage, s.n_ticks) for s in segs] == [
        (GaitStage.DOUBLE_SUPPORT, 1),
        (GaitStage.RIGHT_SUPPORT, 1),
        (GaitStage.NO_CONTACT, 2),
    ]
    assert split_gait_stages([True], [False]) == [GaitSegment(GaitStage.LEFT_SUPPORT, 0, 1)]


def test_passive_ankles_give_one():
    left, right = schedule()
    tau = np.zeros((16, 5))
    tau[:, 4] = np.linspace(10.0, 50.0, 16)
    pgm = passivity_gait_measure(tau, left, right, left_ankle=LEFT, right_ankle=RIGHT)
    assert pgm == (1.0, 1.0, 1.0)


def test_only_the_ankles_working_gives_zero():
    left, right = schedule()
    tau = np.zeros((16, 5))
    tau[:, :4] = 7.0
    pgm = passivity_gait_measure(tau, left, right, left_ankle=LEFT, right_ankle=RIGHT)
    # Double support: both ankles are the stance ankles -> 0. Single support: the stance ankle carries half
    # of the squared torque -> 1 - sqrt(1/2); same for the flying ankle.
    assert pgm.double_support == pytest.approx(0.0)
    assert pgm.single_support == pytest.approx(1 - np.sqrt(0.5))
    assert pgm.flying_foot == pytest.approx(1 - np.sqrt(0.5))


def test_stance_ankle_only_in_single_support():
    left, right = schedule()
    tau = np.zeros((16, 5))
    tau[left & ~right, 0:2] = 5.0   # left ankle works on left support
    tau[right & ~left, 2:4] = -5.0  # right ankle works on right support
    pgm = passivity_gait_measure(tau, left, right, left_ankle=LEFT, right_ankle=RIGHT)
    assert pgm.single_support == pytest.approx(0.0)
    assert pgm.flying_foot == 1.0
    assert np.isnan(pgm.double_support)  # no torque at all in double support


def test_known_ratio_and_pooling():
    # Ankle 3 N m against a knee 4 N m: RMS(tau_sa) / RMS(tau_tot) = 3 / 5.
    left = np.ones(10, dtype=bool)
    right = np.ones(10, dtype=bool)
    tau = np.zeros((10, 5))
    tau[:, 0], tau[:, 4] = 3.0, 4.0
    pgm = passivity_gait_measure(tau, left, right, left_ankle=LEFT, right_ankle=RIGHT)
    assert pgm.double_support == pytest.approx(0.4)
    assert np.isnan(pgm.single_support) and np.isnan(pgm.flying_foot)
    # Tick durations weight the integrals: a tick with only ankle torque lasting 3x longer.
    tau2 = np.array([[1.0, 0, 0, 0, 0], [0, 0, 0, 0, 1.0]])
    pgm = passivity_gait_measure(tau2, [1, 1], [1, 1], left_ankle=LEFT, right_ankle=RIGHT, dt=[0.3, 0.1])
    assert pgm.double_support == pytest.approx(1 - np.sqrt(0.75))


def test_torque_rms_eq12():
    tau = np.array([[3.0, 4.0], [0.0, 0.0]])
    assert torque_rms(tau) == pytest.approx(np.sqrt(25.0 / 2))
    assert torque_rms(tau, dt=[3.0, 1.0]) == pytest.approx(np.sqrt(75.0 / 4))
    assert torque_rms(np.full(7, -2.0)) == pytest.approx(2.0)


def test_bad_input_raises():
    left, right = schedule()
    tau = np.zeros((16, 5))
    kw = {"left_ankle": LEFT, "right_ankle": RIGHT}
    with pytest.raises(ValueError, match="mismatched lengths"):
        passivity_gait_measure(tau[:-1], left, right, **kw)
    with pytest.raises(ValueError, match="mismatched lengths"):
        split_gait_stages(left, right[:-1])
    with pytest.raises(ValueError, match="non-finite"):
        bad = tau.copy()
        bad[3, 2] = np.nan
        passivity_gait_measure(bad, left, right, **kw)
    with pytest.raises(ValueError, match="empty"):
        passivity_gait_measure(np.zeros((0, 5)), [], [], **kw)
    with pytest.raises(ValueError, match="booleans"):
        split_gait_stages([0.5, 1.0], [1, 1])
    with pytest.raises(ValueError, match="booleans"):
        split_gait_stages([], [])
    with pytest.raises(ValueError, match=r"\[0, 5\)"):
        passivity_gait_measure(tau, left, right, left_ankle=[0, 5], right_ankle=RIGHT)
    with pytest.raises(ValueError, match="share columns"):
        passivity_gait_measure(tau, left, right, left_ankle=[0, 1], right_ankle=[1, 2])
    with pytest.raises(ValueError, match="joint column indices"):
        passivity_gait_measure(tau, left, right, left_ankle=[], right_ankle=RIGHT)
    with pytest.raises(ValueError, match="dt"):
        passivity_gait_measure(tau, left, right, dt=-1e-3, **kw)
    with pytest.raises(ValueError, match="n_joints"):
        passivity_gait_measure(np.zeros(16), left, right, **kw)



@settings(max_examples=60, deadline=None)
@given(st.integers(1, 30).flatmap(lambda n: st.tuples(
    arrays(float, (n, 5), elements=st.floats(-50.0, 50.0, allow_nan=False)),
    arrays(bool, n), arrays(bool, n))))
def test_pgm_is_between_zero_and_one(draw):
    tau, left, right = draw
    pgm = passivity_gait_measure(tau, left, right, left_ankle=LEFT, right_ankle=RIGHT)
    for value in pgm:
        assert np.isnan(value) or -1e-12 <= value <= 1.0 + 1e-12
    segs = split_gait_stages(left, right)
    assert segs[0].start == 0 and segs[-1].stop == len(left)
    assert all(a.stop == b.start and a.stage != b.stage for a, b in zip(segs, segs[1:]))
