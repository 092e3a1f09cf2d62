"""Preview control: accurate gains at 1 kHz, rest stays rest, integral action, cart-table output."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.planning import cart_table, preview_gains, simulate_preview


@pytest.mark.parametrize("dt", [0.005, 0.001])
def test_gains_pass_accuracy_checks(dt):
    g = preview_gains(dt, 0.87)
    assert g.refinement_change < 1e-9
    assert g.riccati_residual < 1e-12
    assert g.spectral_radius < 1.0
    assert len(g.Gd) == round(2.5 / dt)
    assert abs(g.Gd[-1]) < 1e-2 * abs(g.Gd[0])  # the preview gains have decayed at the horizon
    assert preview_gains(dt, 0.87) is g  # cached


def test_gains_accurate_below_one_millisecond():
    # The scaled Newton refinement keeps the check meaningful where the raw Riccati problem is worst.
    g = preview_gains(0.0005, 0.87)
    assert g.refinement_change < 1e-8 and g.riccati_residual < 1e-12


def test_cart_table_output():
    A, B, C = cart_table(0.001, 0.87, 9.81)
    x = np.array([0.1, 0.2, 0.3])
    assert C @ x == pytest.approx(0.1 - 0.87 / 9.81 * 0.3)
    np.testing.assert_allclose(A @ x + B * 2.0, [0.1 + 0.2e-3 + 0.15e-6 + 2.0e-9 / 6, 0.2 + 0.3e-3 + 1e-6, 0.3 + 2e-3])


def test_rest_stays_exactly_at_rest_away_from_origin():
    g = preview_gains(0.001, 0.87)
    ref = np.full((3000, 2), [1.234, -0.5])
    states, jerk = simulate_preview(g, ref)
    np.testing.assert_array_equal(states[:, 0, :], ref)
    np.testing.assert_array_equal(states[:, 1:, :], 0.0)
    np.testing.assert_array_equal(jerk, 0.0)


def test_integral_action_reaches_a_step_reference():
    g = preview_gains(0.005, 0.87)
    ref = np.concatenate([np.zeros(600), np.full(1400, 0.1)])
    states, _ = simulate_preview(g, ref)
    zmp = states[:, 0] - 0.87 / 9.81 * states[:, 2]
    assert zmp[-1] == pytest.approx(0.1, abs=1e-6)
    assert states[-1, 0] == pytest.approx(0.1, abs=1e-6)
    # The CoM anticipates the step (preview) and the ZMP first moves the other way (non-minimum phase).
    assert states[599, 0] > 0.01
    assert zmp[:600].min() < -1e-4


def test_invalid_arguments():
    with pytest.raises(ValueError, match="com_height"):
        preview_gains(0.001, 0.0)
    with pytest.raises(ValueError, match="horizon"):
        preview_gains(0.01, 0.87, horizon=0.001)
    g = preview_gains(0.005, 0.87)
    with pytest.raises(ValueError, match="zmp_ref"):
        simulate_preview(g, np.array([np.nan, 0.0]))
