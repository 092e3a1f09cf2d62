"""DCM of the LIPM (Eq. 2)."""

import numpy as np
import pytest

from wbcbench.estimation import dcm, lipm_omega


def test_omega():
    assert lipm_omega(0.981, gravity=9.81) == pytest.approx(np.sqrt(10.0))
    np.testing.assert_allclose(lipm_omega(np.array([1.0, 4.0]), gravity=4.0), [2.0, 1.0])


def test_dcm_single_and_batched():
    np.testing.assert_allclose(dcm([0.1, 0.0, 0.9], [0.3, -0.6, 0.0], 3.0), [0.2, -0.2, 0.9])
    com = np.zeros((3, 3))
    vel = np.tile([1.0, 0.0, 0.0], (3, 1))
    np.testing.assert_allclose(dcm(com, vel, np.array([1.0, 2.0, 4.0]))[:, 0], [1.0, 0.5, 0.25])


def test_dcm_of_a_lipm_solution_is_constant_on_the_divergent_mode():
    # c(t) = z + a e^{omega t} + b e^{-omega t}: xi - z = 2 a e^{omega t} (the divergent part only).
    omega, z, a, b = 3.0, 0.05, 0.01, 0.02
    t = np.linspace(0.0, 0.5, 11)
    c = z + a * np.exp(omega * t) + b * np.exp(-omega * t)
    cd = omega * (a * np.exp(omega * t) - b * np.exp(-omega * t))
    xi = dcm(np.stack([c, 0 * c, 0 * c + 1], 1), np.stack([cd, 0 * c, 0 * c], 1), omega)
    np.testing.assert_allclose(xi[:, 0], z + 2 * a * np.exp(omega * t))


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], 0.0), "omega"),
        (([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], np.array([1.0, np.nan])), "omega"),
        ((np.zeros((2, 3)), np.zeros((3, 3)), 1.0), "mismatched lengths"),
        ((np.zeros((2, 3)), np.zeros((2, 3)), np.ones(3)), "mismatched lengths"),
        (([0.0, np.inf, 1.0], [0.0, 0.0, 0.0], 1.0), "non-finite"),
        ((np.zeros((0, 3)), np.zeros((0, 3)), 1.0), "empty"),
    ],
)
def test_dcm_bad_input(args, match):
    with pytest.raises(ValueError, match=match):
        dcm(*args)


def test_omega_bad_input():
    with pytest.raises(ValueError, match="com_height"):
        lipm_omega(0.0)
    with pytest.raises(ValueError, match="gravity"):
        lipm_omega(1.0, gravity=-9.81)
