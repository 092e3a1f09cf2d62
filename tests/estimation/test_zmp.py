"""CoP and ZMP: point forces with known answers, the load threshold, tilted planes, bad input."""

import numpy as np
import pytest

from wbcbench.estimation import Plane, Wrench, center_of_pressure, zmp_from_wrenches


def point_force(force, point, ref=(0.0, 0.0, 0.0)):
    """A pure force applied at `point`, reduced to `ref`."""
    force, point, ref = (np.asarray(a, dtype=float) for a in (force, point, ref))
    return Wrench(force, np.cross(point - ref, force), np.broadcast_to(ref, force.shape).copy())


def test_single_vertical_force_zmp_is_its_point():
    w = point_force([0.0, 0.0, 400.0], [0.3, -0.1, 0.0], ref=[1.0, 2.0, 0.5])
    np.testing.assert_allclose(zmp_from_wrenches([w]), [0.3, -0.1, 0.0], atol=1e-12)
    cop = center_of_pressure(w)
    np.testing.assert_allclose(cop.point, [0.3, -0.1, 0.0], atol=1e-12)
    assert cop.loaded and cop.normal_force == pytest.approx(400.0)


def test_two_equal_vertical_forces_give_the_midpoint():
    left = point_force([0.0, 0.0, 300.0], [0.1, 0.09, 0.0])
    right = point_force([0.0, 0.0, 300.0], [0.3, -0.09, 0.0], ref=[0.3, -0.09, 0.1])
    np.testing.assert_allclose(zmp_from_wrenches([left, right]), [0.2, 0.0, 0.0], atol=1e-12)


def test_unequal_forces_give_the_force_weighted_mean():
    left = point_force([0.0, 0.0, 100.0], [0.0, 0.1, 0.0])
    right = point_force([0.0, 0.0, 300.0], [0.0, -0.1, 0.0])
    np.testing.assert_allclose(zmp_from_wrenches([left, right]), [0.0, -0.05, 0.0], atol=1e-12)


def test_ground_height_and_tangential_force():
    # A force with a tangential part applied at (0.2, 0, 0.1): on the plane z = 0.1 its CoP is the point.
    w = point_force([30.0, -20.0, 500.0], [0.2, 0.0, 0.1])
    np.testing.assert_allclose(zmp_from_wrenches([w], ground=0.1), [0.2, 0.0, 0.1], atol=1e-12)
    # Projected to z = 0 along the force line: the ZMP moves by -h F_t / F_z.
    expected = [0.2 - 0.1 * 30 / 500, 0.1 * 20 / 500, 0.0]
    np.testing.assert_allclose(zmp_from_wrenches([w]), expected, atol=1e-12)


def test_tilted_plane():
    n = np.array([0.0, np.sin(0.2), np.cos(0.2)])
    point = np.array([0.5, 0.1, 0.05])
    plane = Plane(np.array([0.4, 0.0, 0.05 + 0.1 * np.tan(0.2)]), 3.0 * n)  # normal need not be unit
    assert abs((point - plane.point) @ n) < 1e-12
    w = point_force(250.0 * n + [5.0, 0.0, 0.0], point)
    cop = center_of_pressure(w, plane)
    np.testing.assert_allclose(cop.point, point, atol=1e-12)
    np.testing.assert_allclose(cop.normal_force, 250.0)


def test_cop_threshold():
    light = point_force([0.0, 0.0, 5.0], [0.1, 0.0, 0.0])
    cop = center_of_pressure(light)
    assert not cop.loaded and np.all(np.isnan(cop.point))
    assert cop.normal_force == pytest.approx(5.0)
    assert center_of_pressure(light, min_normal_force=1.0).loaded
    at_threshold = point_force([0.0, 0.0, 10.0], [0.1, 0.0, 0.0])
    assert center_of_pressure(at_threshold).loaded  # "below 10 N" is unloaded; 10 N is loaded
    pulling = point_force([0.0, 0.0, -50.0], [0.1, 0.0, 0.0])
    assert not center_of_pressure(pulling, min_normal_force=0.0).loaded


def test_zmp_drops_unloaded_feet_and_is_nan_without_support():
    stance = point_force([0.0, 0.0, 800.0], [0.2, -0.1, 0.0])
    swing = Wrench(np.array([3.0, 1.0, 4.0]), np.array([0.5, -0.7, 0.1]), np.array([0.0, 0.1, 0.1]))
    np.testing.assert_allclose(zmp_from_wrenches([stance, swing]), [0.2, -0.1, 0.0], atol=1e-12)
    assert np.all(np.isnan(zmp_from_wrenches([swing])))
    # With no threshold the swing residual does enter.
    assert not np.allclose(zmp_from_wrenches([stance, swing], min_normal_force=0.0), [0.2, -0.1, 0.0])


def test_batched_zmp_equals_weighted_cops():
    rng = np.random.default_rng(3)
    n = 100
    fz = rng.uniform(20.0, 600.0, size=(2, n))
    pts = np.concatenate([rng.uniform(-0.2, 0.2, size=(2, n, 2)), np.zeros((2, n, 1))], axis=2)
    tangential = rng.normal(scale=20.0, size=(2, n, 2))
    forces = np.concatenate([tangential, fz[..., None]], axis=2)
    refs = rng.normal(size=(2, n, 3))
    wrenches = [point_force(forces[k], pts[k], refs[k]) for k in range(2)]
    zmp = zmp_from_wrenches(wrenches)
    cops = [center_of_pressure(w).point for w in wrenches]
    expected = (fz[0, :, None] * cops[0] + fz[1, :, None] * cops[1]) / fz.sum(axis=0)[:, None]
    assert zmp.shape == (n, 3)
    np.testing.assert_allclose(zmp, expected, atol=1e-12)
    # The CoP does not depend on the reduction point of the wrench.
    np.testing.assert_allclose(center_of_pressure(wrenches[0].at(np.zeros(3))).point, cops[0], atol=1e-12)


def test_per_tick_threshold_in_a_batch():
    fz = np.array([500.0, 5.0, 0.0])
    w = point_force(np.stack([np.zeros(3), np.zeros(3), fz], axis=1), np.tile([0.1, 0.0, 0.0], (3, 1)))
    cop = center_of_pressure(w)
    np.testing.assert_array_equal(cop.loaded, [True, False, False])
    np.testing.assert_allclose(cop.point[0], [0.1, 0.0, 0.0], atol=1e-12)
    assert np.all(np.isnan(cop.point[1:]))


def test_bad_input_raises():
    w = point_force([0.0, 0.0, 100.0], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="non-empty sequence"):
        zmp_from_wrenches([])
    with pytest.raises(ValueError, match="non-empty sequence"):
        zmp_from_wrenches(w)
    with pytest.raises(ValueError, match="mismatched lengths"):
        zmp_from_wrenches([point_force(np.tile([0, 0, 1.0], (3, 1)), np.zeros((3, 3))),
                           point_force(np.tile([0, 0, 1.0], (4, 1)), np.zeros((4, 3)))])
    with pytest.raises(ValueError, match="non-finite"):
        center_of_pressure(Wrench(np.array([0.0, 0.0, np.nan]), np.zeros(3), np.zeros(3)))
    with pytest.raises(ValueError, match="min_normal_force"):
        center_of_pressure(w, min_normal_force=-1.0)
    with pytest.raises(ValueError, match="ground"):
        center_of_pressure(w, ground="floor")
    with pytest.raises(ValueError, match="non-zero"):
        center_of_pressure(w, Plane(np.zeros(3), np.zeros(3)))
    with pytest.raises(ValueError, match="Wrench"):
        center_of_pressure((np.zeros(3), np.zeros(3), np.zeros(3)))
