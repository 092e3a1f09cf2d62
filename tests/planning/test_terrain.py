"""Terrain for planning: boxes -> top faces as contact surfaces, the scenario geometries, sole-box penetration."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbcbench.config import Section
from wbcbench.planning import (
    ContactSurface,
    ContactTerrain,
    OrientedBox,
    SoleRectangle,
    boxes_to_yaml,
    platform_boxes,
    rpy_matrix,
    stairs_boxes,
)
from wbcbench.planning.terrain import _obb_penetration
from wbcbench.scene import Box, Terrain, parse_terrain, stairs

SOLE = SoleRectangle(0.20, 0.13)
angles = st.floats(-np.pi, np.pi, allow_nan=False)


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@given(angles, angles, angles)
def test_rpy_is_rz_ry_rx(r, p, y):
    np.testing.assert_allclose(rpy_matrix(r, p, y), _rz(y) @ _ry(p) @ _rx(r), atol=1e-12)


def test_rpy_matches_the_simulator_convention():
    pin = pytest.importorskip("pinocchio")  # the simulator builds box quaternions with pin.rpy.rpyToMatrix
    rng = np.random.default_rng(0)
    for rpy in rng.uniform(-np.pi, np.pi, size=(20, 3)):
        np.testing.assert_allclose(rpy_matrix(*rpy), pin.rpy.rpyToMatrix(*rpy), atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(angles, st.floats(-1.2, 1.2), angles, st.tuples(*[st.floats(0.05, 2.0)] * 3))
def test_top_face_is_the_upmost_face_counter_clockwise_with_outward_normal(r, p, y, size):
    box = OrientedBox.from_box(Box(center=(0.3, -0.2, 0.5), size=size, rpy=(r, p, y)))
    verts, n = box.top_face()
    # the face's normal is the box axis (or its opposite) with the largest z component, pointing outward
    assert n[2] == pytest.approx(np.abs(box.R[2]).max())
    face_center = verts.mean(axis=0)
    assert (face_center - box.center) @ n > 0.0
    np.testing.assert_allclose((verts - face_center) @ n, 0.0, atol=1e-12)
    # its vertices are box vertices
    all_v = box.vertices()
    for v in verts:
        assert np.min(np.linalg.norm(all_v - v, axis=1)) < 1e-12
    # counter-clockwise seen from the normal
    e1, e2 = verts[1] - verts[0], verts[2] - verts[1]
    assert np.cross(e1, e2) @ n > 0.0


def test_stairs_surfaces_are_the_treads():
    terrain = ContactTerrain.from_boxes(stairs_boxes())
    names = [s.name for s in terrain.surfaces]
    assert names == ["floor"] + [f"step_{i}" for i in range(1, 7)]
    for i, s in enumerate(terrain.surfaces[1:], start=1):
        np.testing.assert_allclose(s.normal, [0, 0, 1], atol=1e-12)
        np.testing.assert_allclose(s.vertices[:, 2], 0.1 * i, atol=1e-12)
        x = s.vertices[:, 0]
        assert x.min() == pytest.approx(0.3 + 0.3 * (i - 1)) and x.max() == pytest.approx(0.3 + 0.3 * i)
        np.testing.assert_allclose(np.sort(np.unique(np.round(s.vertices[:, 1], 9))), [-0.5, 0.5])
    assert stairs_boxes() == stairs(6, 0.10, 0.30, 1.0, 0.3)


def test_platform_geometry():
    boxes = platform_boxes()
    assert [b.name for b in boxes] == [f"platform_{i}" for i in range(1, 7)]
    terrain = ContactTerrain.from_boxes(boxes)
    ridge = 0.30 * np.tan(np.deg2rad(15.0))
    assert ridge == pytest.approx(0.0804, abs=1e-4)
    for i, s in enumerate(terrain.surfaces[1:]):
        assert np.rad2deg(s.slope) == pytest.approx(15.0)
        rising = i % 2 == 0
        assert np.sign(s.normal[0]) == (-1.0 if rising else 1.0)   # normal leans against the slope
        assert s.normal[1] == pytest.approx(0.0, abs=1e-12)
        x0, x1 = 0.15 + 0.3 * i, 0.15 + 0.3 * (i + 1)
        assert s.vertices[:, 0].min() == pytest.approx(x0) and s.vertices[:, 0].max() == pytest.approx(x1)
        z0, z1 = (0.0, ridge) if rising else (ridge, 0.0)
        assert float(s.height_at(np.array([x0, 0.0]))) == pytest.approx(z0, abs=1e-12)
        assert float(s.height_at(np.array([x1, 0.0]))) == pytest.approx(z1, abs=1e-12)
    # contiguous: the tops meet at the ridges and valleys, and no box rises above a neighbour's top
    xs = np.linspace(0.16, 1.94, 300)
    for x in xs:
        assert terrain.height_at([x, 0.2]) <= ridge + 1e-9
    with pytest.raises(ValueError, match="even"):
        platform_boxes(count=5)
    with pytest.raises(ValueError, match="slope"):
        platform_boxes(slope_deg=50.0)


@pytest.mark.parametrize("boxes", [stairs_boxes(), platform_boxes(), platform_boxes(slope_deg=20.0, count=4)])
def test_yaml_round_trip_gives_the_same_surfaces(boxes):
    raw = boxes_to_yaml(boxes, friction=0.8)
    terrain = parse_terrain(Section(raw, "scenario.yaml", "terrain"))
    assert terrain.friction == 0.8 and terrain.floor
    a = ContactTerrain.from_terrain(terrain)
    b = ContactTerrain.from_boxes(boxes)
    assert [s.name for s in a.surfaces] == [s.name for s in b.surfaces]
    for sa, sb in zip(a.surfaces, b.surfaces):
        np.testing.assert_allclose(sa.vertices, sb.vertices, atol=1e-5)
        np.testing.assert_allclose(sa.normal, sb.normal, atol=1e-5)


def test_terrain_from_the_simulator_terrain():
    t = Terrain(kind="stairs", boxes=stairs(6, 0.1, 0.3), friction=0.7, floor=False)
    ct = ContactTerrain.from_terrain(t)
    assert not ct.floor and ct.friction == 0.7
    assert [s.name for s in ct.surfaces] == [f"step_{i}" for i in range(1, 7)]


def test_steep_boxes_give_no_surface_and_names_are_checked():
    wall = Box(center=(1, 0, 0.5), size=(0.1, 1.0, 1.0), rpy=(0.0, np.pi / 4, 0.0))  # no face flatter than 45 deg
    terrain = ContactTerrain.from_boxes([wall])
    assert [s.name for s in terrain.surfaces] == ["floor"]
    assert len(terrain.boxes) == 1
    with pytest.raises(ValueError, match="unique"):
        ContactTerrain.from_boxes([Box((0, 0, 0), (1, 1, 1), name="a"), Box((2, 0, 0), (1, 1, 1), name="a")])
    with pytest.raises(ValueError, match="size"):
        ContactTerrain.from_boxes([Box((0, 0, 0), (1, -1, 1))])
    with pytest.raises(ValueError, match="no contact surface"):
        ContactTerrain.from_boxes([wall], floor=False)


def test_surface_queries():
    s = ContactTerrain.from_boxes(platform_boxes()).surface("platform_1")
    xy = np.array([[0.3, 0.0], [0.3, 0.6], [0.1, 0.0]])
    np.testing.assert_array_equal(s.contains_xy(xy), [True, False, False])
    R = s.foot_rotation(0.0)
    np.testing.assert_allclose(R[:, 2], s.normal)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert R[1, 0] == pytest.approx(0.0) and R[0, 0] > 0.0     # heading along +x, in the plane
    p = np.array([0.3, 0.085, float(s.height_at(np.array([0.3, 0.085])))])
    assert float(s.distance_to_plane(p)) == pytest.approx(0.0, abs=1e-12)
    # the 0.20 m foot centred on the 0.31 m slope: (0.3106 - 0.20) / 2 = 0.0553 m of margin along the slope
    assert s.footprint_margin(p, R, SOLE) == pytest.approx((0.30 / np.cos(np.deg2rad(15)) - 0.20) / 2, abs=1e-9)
    with pytest.raises(ValueError, match="no contact surface 'nope'"):
        ContactTerrain.from_boxes(platform_boxes()).surface("nope")
    with pytest.raises(ValueError, match="convex"):
        ContactSurface("bad", np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])[::-1], np.array([0, 0, 1.0]))


def test_sole_penetration_on_stairs():
    terrain = ContactTerrain.from_boxes(stairs_boxes())
    R = np.eye(3)
    # standing on tread 1: touching, not penetrating; 1 mm lower penetrates by 1 mm
    assert terrain.sole_penetration(np.array([0.45, 0.0, 0.1]), R, SOLE) == pytest.approx(0.0, abs=1e-12)
    assert terrain.sole_penetration(np.array([0.45, 0.0, 0.099]), R, SOLE) == pytest.approx(0.001, abs=1e-9)
    # toe 1 cm into the riser of tread 1 (floor level): 1 cm
    assert terrain.sole_penetration(np.array([0.21, 0.0, 0.0]), R, SOLE) == pytest.approx(0.01, abs=1e-9)
    # in the air: negative, at most minus the distance (8 cm above tread 1, 2 cm below the riser of tread 2)
    assert -0.08 - 1e-12 <= terrain.sole_penetration(np.array([0.45, 0.0, 0.18]), R, SOLE) < 0.0
    assert terrain.sole_penetration(np.array([0.45, 0.0, 0.18]), R, SOLE) == pytest.approx(-0.05, abs=1e-9)
    # vectorised = one by one
    ps = np.array([[0.45, 0.0, 0.1], [0.45, 0.0, 0.099], [0.21, 0.0, 0.0], [1.0, 0.3, 0.25]])
    Rs = np.broadcast_to(R, (4, 3, 3))
    np.testing.assert_allclose(terrain.sole_penetration(ps, Rs, SOLE),
                               [terrain.sole_penetration(p, R, SOLE) for p in ps])


@settings(max_examples=80, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6), angles, angles, angles, angles)
def test_box_penetration_agrees_with_sampled_points(offsets, r1, p1, r2, y2):
    """Separating axes: if any point of box A lies inside box B, the reported depth is > 0."""
    A = OrientedBox(np.array(offsets[:3]) * 0.3, rpy_matrix(r1, p1, 0.0), np.array([0.1, 0.065, 0.01]))
    B = OrientedBox(np.array(offsets[3:]) * 0.3, rpy_matrix(r2, 0.0, y2), np.array([0.2, 0.1, 0.15]))
    depth = _obb_penetration(A.center[None], A.R[None], A.half, B.center[None], B.R[None], B.half[None])[0, 0]
    grid = np.stack(np.meshgrid(*[np.linspace(-1, 1, 7)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    points = A.center + (grid * A.half) @ A.R.T
    local = (points - B.center) @ B.R
    inside = np.all(np.abs(local) < B.half - 1e-9, axis=1)
    if inside.any():
        assert depth > 0.0
    # symmetric
    back = _obb_penetration(B.center[None], B.R[None], B.half, A.center[None], A.R[None], A.half[None])[0, 0]
    if depth > -1e-3 or back > -1e-3:
        assert back == pytest.approx(depth, abs=1e-9)
