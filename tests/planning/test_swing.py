"""Swing trajectories: rest at both ends, exact apex, consistent derivatives, geodesic rotation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.planning import Footstep, Side, SwingTrajectory, quintic_blend
from wbcbench.planning.geometry import rotation_from_yaw, so3_exp, so3_log


def make(z0=0.0, z1=0.0, yaw0=0.0, yaw1=0.3, apex=0.05, phase=0.5, window=(0.0, 1.0), duration=0.9):
    return SwingTrajectory(np.array([0.0, -0.0857, z0]), rotation_from_yaw(yaw0), np.array([0.4, -0.05, z1]),
                           rotation_from_yaw(yaw1), t_start=2.0, duration=duration, apex_height=apex,
                           apex_phase=phase, horizontal_window=window)


def test_quintic_blend_ends():
    q, dq, ddq = quintic_blend(np.array([0.0, 1.0, -1.0, 2.0]))
    np.testing.assert_allclose(q, [0, 1, 0, 1])
    np.testing.assert_allclose(dq, 0.0)
    np.testing.assert_allclose(ddq, 0.0)


@pytest.mark.parametrize("kwargs", [{}, {"z1": 0.1}, {"z1": -0.1, "phase": 0.3}, {"window": (0.2, 0.8)},
                                    {"duration": 0.711}])
def test_rest_at_lift_off_and_touch_down(kwargs):
    sw = make(**kwargs)
    for t in (sw.t_start, sw.t_end):
        s = sw.at(t)
        np.testing.assert_allclose(s.v_world_sole, 0.0, atol=1e-12)
        np.testing.assert_allclose(s.a_world_sole, 0.0, atol=1e-12)
        np.testing.assert_allclose(s.w_world_sole, 0.0, atol=1e-12)
        np.testing.assert_allclose(s.dw_world_sole, 0.0, atol=1e-12)
    np.testing.assert_allclose(sw.at(sw.t_start).p_world_sole, sw.p_world_start, atol=1e-12)
    np.testing.assert_allclose(sw.at(sw.t_end).p_world_sole, sw.p_world_end, atol=1e-12)
    np.testing.assert_allclose(sw.at(sw.t_end).R_world_sole, sw.R_world_end, atol=1e-12)
    # Also at rest just outside the swing, and continuous there.
    before, after = sw.at(sw.t_start - 0.1), sw.at(sw.t_end + 0.1)
    np.testing.assert_allclose(before.p_world_sole, sw.p_world_start)
    np.testing.assert_allclose(after.p_world_sole, sw.p_world_end, atol=1e-12)
    eps = 1e-4
    near = sw.at(sw.t_start + eps)
    assert np.linalg.norm(near.v_world_sole) < 1e-5  # velocity grows as t^2
    assert np.linalg.norm(near.a_world_sole) < 0.1  # acceleration grows as t


@pytest.mark.parametrize("z0, z1, apex, phase", [(0.0, 0.0, 0.05, 0.5), (0.0, 0.1, 0.05, 0.6), (0.1, 0.0, 0.08, 0.4)])
def test_apex_reached_exactly(z0, z1, apex, phase):
    sw = make(z0=z0, z1=z1, apex=apex, phase=phase)
    t = np.linspace(sw.t_start, sw.t_end, 9001)
    z = sw.sample(t).p_world_sole[:, 2]
    assert z.max() == pytest.approx(max(z0, z1) + apex, abs=1e-12)
    assert sw.at(sw.t_start + phase * sw.duration).p_world_sole[2] == pytest.approx(sw.z_apex, abs=1e-12)
    assert z.min() >= min(z0, z1) - 1e-12  # never below the lower end


def test_horizontal_window_holds_foot_in_place():
    sw = make(window=(0.25, 0.75))
    early = sw.at(sw.t_start + 0.2 * sw.duration)
    np.testing.assert_allclose(early.p_world_sole[:2], sw.p_world_start[:2], atol=1e-12)
    assert early.p_world_sole[2] > sw.p_world_start[2]


def test_derivatives_match_finite_differences():
    sw = make(z1=0.1, yaw1=0.5, phase=0.4, window=(0.1, 0.9))
    h = 1e-6
    for t in np.linspace(sw.t_start + 0.01, sw.t_end - 0.01, 23):
        s, sp, sm = sw.at(t), sw.at(t + h), sw.at(t - h)
        np.testing.assert_allclose(s.v_world_sole, (sp.p_world_sole - sm.p_world_sole) / (2 * h), atol=1e-6)
        np.testing.assert_allclose(s.a_world_sole, (sp.v_world_sole - sm.v_world_sole) / (2 * h), atol=1e-4)
        w_fd = so3_log(sp.R_world_sole @ sm.R_world_sole.T) / (2 * h)
        np.testing.assert_allclose(s.w_world_sole, w_fd, atol=1e-6)
        np.testing.assert_allclose(s.dw_world_sole, (sp.w_world_sole - sm.w_world_sole) / (2 * h), atol=1e-4)


def test_yaw_follows_the_geodesic():
    sw = make(yaw0=0.1, yaw1=0.7)
    mid = sw.at(sw.t_start + 0.5 * sw.duration)
    np.testing.assert_allclose(mid.R_world_sole, rotation_from_yaw(0.4), atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(axis=st.lists(st.floats(-1, 1), min_size=3, max_size=3), angle=st.floats(0.0, 1.0),
       tau=st.floats(0.0, 1.0))
def test_general_rotation_is_on_so3(axis, angle, tau):
    a = np.array(axis)
    if np.linalg.norm(a) < 1e-3:
        a = np.array([0.0, 0.0, 1.0])
    R1 = so3_exp(angle * a / np.linalg.norm(a))
    if R1[2, 2] <= 0.0:
        return
    sw = SwingTrajectory(np.zeros(3), np.eye(3), np.ones(3) * 0.1, R1, 0.0, 1.0)
    R = sw.at(tau).R_world_sole
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_between_footsteps_and_validation():
    a = Footstep.from_xyz_yaw(Side.LEFT, 0, 0.1)
    b = Footstep.from_xyz_yaw(Side.LEFT, 0.2, 0.1)
    sw = SwingTrajectory.between(a, b, 1.0, 0.8, apex_height=0.07)
    assert sw.z_apex == pytest.approx(0.07)
    with pytest.raises(ValueError, match="same foot"):
        SwingTrajectory.between(a, Footstep.from_xyz_yaw(Side.RIGHT, 0.2, -0.1), 1.0, 0.8)
    with pytest.raises(ValueError, match="duration"):
        SwingTrajectory.between(a, b, 1.0, 0.0)
    with pytest.raises(ValueError, match="apex_height"):
        SwingTrajectory.between(a, b, 1.0, 0.5, apex_height=-0.01)
    with pytest.raises(ValueError, match="apex_phase"):
        SwingTrajectory.between(a, b, 1.0, 0.5, apex_phase=1.0)
    with pytest.raises(ValueError, match="horizontal_window"):
        SwingTrajectory.between(a, b, 1.0, 0.5, horizontal_window=(0.6, 0.4))
