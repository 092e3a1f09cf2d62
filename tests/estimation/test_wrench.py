"""Ankle F/T reading -> contact wrench: a hand-built static case, random round trips, bad input."""

import numpy as np
import pytest

from wbcbench.estimation import FootMass, Wrench, contact_wrench_from_ft, ft_from_contact_wrench

G = np.array([0.0, 0.0, -9.81])
YAW_90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # sensor x -> world y


def random_rotations(rng, n):
    q = rng.normal(size=(n, 4))
    w, x, y, z = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
        ],
        axis=1,
    )


def test_static_foot_hand_built():
    # Foot at rest, sensor at p_site, rotated 90 deg about z; 500 N vertical contact force at a point
    # 2 cm ahead (world x) of the site, on the ground. Foot 1.6 kg, CoM (-0.02, 0, -0.06) in the sensor frame.
    #   contact moment about the site: (0.02, 0, -0.107) x (0, 0, 500) = (0, -10, 0)
    #   leg force on foot: -(0, 0, 500) - 1.6 (0, 0, -9.81) = (0, 0, -484.304)
    #   CoM offset in world R (-0.02, 0, -0.06) = (0, -0.02, -0.06); x (0, 0, -15.696) = (0.31392, 0, 0)
    #   leg moment on foot about the site: -(0, -10, 0) - (0.31392, 0, 0) = (-0.31392, 10, 0)
    #   in the sensor frame (R^T): f_s = (0, 0, -484.304), m_s = (10, 0.31392, 0)
    p_site = np.array([0.1, 0.2, 0.107])
    p_cop = np.array([0.12, 0.2, 0.0])
    foot = FootMass(1.6, np.array([-0.02, 0.0, -0.06]))
    f_s = np.array([0.0, 0.0, -484.304])
    m_s = np.array([10.0, 0.31392, 0.0])

    at_site = contact_wrench_from_ft(f_s, m_s, YAW_90, p_site, foot)
    np.testing.assert_allclose(at_site.force, [0.0, 0.0, 500.0], atol=1e-9)
    np.testing.assert_allclose(at_site.moment, [0.0, -10.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(at_site.point, p_site)

    at_cop = contact_wrench_from_ft(f_s, m_s, YAW_90, p_site, foot, p_world_ref=p_cop)
    np.testing.assert_allclose(at_cop.moment, np.zeros(3), atol=1e-9)
    np.testing.assert_allclose(at_cop.point, p_cop)

    f_back, m_back = ft_from_contact_wrench(at_cop, YAW_90, p_site, foot)
    np.testing.assert_allclose(f_back, f_s, atol=1e-9)
    np.testing.assert_allclose(m_back, m_s, atol=1e-9)


def test_massless_foot_is_the_negated_rotated_reading():
    rng = np.random.default_rng(0)
    R = random_rotations(rng, 1)[0]
    f_s, m_s = rng.normal(size=3), rng.normal(size=3)
    w = contact_wrench_from_ft(f_s, m_s, R, np.zeros(3), FootMass(0.0))
    np.testing.assert_allclose(w.force, -R @ f_s)
    np.testing.assert_allclose(w.moment, -R @ m_s)


def test_unloaded_foot_at_rest_reads_its_own_weight():
    # Foot hanging in the air: no contact, so the sensor carries the foot's weight and its moment.
    foot = FootMass(1.60457, np.array([-0.0207, -0.0002, -0.0609]))
    contact = Wrench(np.zeros(3), np.zeros(3), np.zeros(3))
    f_s, m_s = ft_from_contact_wrench(contact, np.eye(3), np.array([0.0, 0.0, 0.5]), foot)
    np.testing.assert_allclose(f_s, [0.0, 0.0, 1.60457 * 9.81])  # leg holds the foot up
    back = contact_wrench_from_ft(f_s, m_s, np.eye(3), np.array([0.0, 0.0, 0.5]), foot)
    np.testing.assert_allclose(back.force, np.zeros(3), atol=1e-12)
    np.testing.assert_allclose(back.moment, np.zeros(3), atol=1e-12)


def test_random_round_trip_batched():
    rng = np.random.default_rng(1)
    n = 200
    R = random_rotations(rng, n)
    p_site = rng.normal(size=(n, 3))
    contact = Wrench(rng.normal(scale=300.0, size=(n, 3)), rng.normal(scale=20.0, size=(n, 3)),
                     rng.normal(size=(n, 3)))
    foot = FootMass(2.3, rng.normal(scale=0.05, size=3))
    f_s, m_s = ft_from_contact_wrench(contact, R, p_site, foot)
    assert f_s.shape == m_s.shape == (n, 3)
    back = contact_wrench_from_ft(f_s, m_s, R, p_site, foot, p_world_ref=contact.point)
    np.testing.assert_allclose(back.force, contact.force, atol=1e-9)
    np.testing.assert_allclose(back.moment, contact.moment, atol=1e-9)


def test_batched_matches_per_sample_and_broadcasts_single_pose():
    rng = np.random.default_rng(2)
    n = 5
    f_s, m_s = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    R = random_rotations(rng, 1)[0]
    p = rng.normal(size=3)
    foot = FootMass(1.0, np.array([0.0, 0.0, -0.05]))
    batched = contact_wrench_from_ft(f_s, m_s, R, p, foot)
    assert batched.force.shape == batched.moment.shape == batched.point.shape == (n, 3)
    for k in range(n):
        one = contact_wrench_from_ft(f_s[k], m_s[k], R, p, foot)
        np.testing.assert_allclose(batched.force[k], one.force)
        np.testing.assert_allclose(batched.moment[k], one.moment)


def test_wrench_at_moves_the_moment():
    w = Wrench(np.array([0.0, 0.0, 100.0]), np.zeros(3), np.array([1.0, 0.0, 0.0]))
    moved = w.at(np.zeros(3))
    np.testing.assert_allclose(moved.moment, [0.0, -100.0, 0.0])  # (1,0,0) x (0,0,100)
    np.testing.assert_allclose(moved.at(w.point).moment, np.zeros(3), atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"force_sensor": np.zeros((4, 3))}, "mismatched lengths"),
        ({"force_sensor": [0.0, np.nan, 0.0]}, "non-finite"),
        ({"force_sensor": np.zeros((0, 3))}, "empty"),
        ({"torque_sensor": np.zeros(2)}, r"shape \(3,\) or \(N, 3\)"),
        ({"R_world_sensor": np.eye(3).ravel()}, "reshape"),
        ({"R_world_sensor": 2.0 * np.eye(3)}, "not a rotation"),
        ({"R_world_sensor": np.diag([1.0, 1.0, -1.0])}, "not a rotation"),
        ({"foot": 1.6}, "FootMass"),
        ({"gravity": np.zeros((2, 3))}, "gravity"),
    ],
)
def test_bad_input_raises(kwargs, match):
    args = {
        "force_sensor": np.zeros((3, 3)),
        "torque_sensor": np.zeros((3, 3)),
        "R_world_sensor": np.eye(3),
        "p_world_sensor": np.zeros(3),
        "foot": FootMass(1.0),
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        contact_wrench_from_ft(**args)


def test_foot_mass_validation():
    with pytest.raises(ValueError, match="mass"):
        FootMass(-1.0)
    with pytest.raises(ValueError, match="p_sensor_com"):
        FootMass(1.0, np.zeros((2, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        FootMass(1.0, np.array([0.0, np.inf, 0.0]))
