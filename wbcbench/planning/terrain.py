"""Terrain for planning: the scene's boxes as oriented boxes and their top faces as contact surfaces.

The simulator builds its scene from `wbcbench.scene.Terrain` (a floor plane at z = 0 and boxes given
by centre, full size and roll-pitch-yaw). The planner reads the same data: `ContactTerrain.from_terrain`
(or `from_boxes`) turns every box into an oriented box (for collision checks) and its top face into a
`ContactSurface`, a convex polygon with its outward unit normal. So the footholds the planner chooses are the
faces MuJoCo collides with.

Conventions:
- Box orientation: R = Rz(yaw) Ry(pitch) Rx(roll), the convention of `pinocchio.rpy.rpyToMatrix`, which the
  simulator uses to build the box quaternion (wbcbench/sim/model.py), reproduced here without pinocchio.
- The top face of a box is its face whose outward normal has the largest world z component; a box whose top
  face is steeper than `max_slope` (default 40 degrees) is an obstacle without a contact surface.
- The floor (if present) is the plane z = 0, a contact surface represented by a square of half side
  `floor_extent` (default 50 m) centred on the origin; the parts of it under boxes are excluded by the
  collision check of each foothold, not by the polygon.
- A surface polygon is (k, 3) world vertices, counter-clockwise seen from the outward normal (from above).

Geometry of the two uneven-terrain scenarios (paper 000, Sections 6.3-6.4) as box lists, for scenario files:
`stairs_boxes` (6 steps of 10 cm x 30 cm by default, `wbcbench.scene.stairs`) and `platform_boxes`
(pitched platforms of alternating slope, 15 degrees by default; see its docstring for the numbers).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import PlanningError
from ..scene import Box, Terrain, stairs
from .geometry import SoleRectangle

__all__ = [
    "rpy_matrix",
    "OrientedBox",
    "ContactSurface",
    "ContactTerrain",
    "sole_box",
    "stairs_boxes",
    "platform_boxes",
    "boxes_to_yaml",
]

_EPS = 1e-9


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rotation Rz(yaw) Ry(pitch) Rx(roll), shape (3, 3) (angles in rad; pinocchio's rpyToMatrix)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class OrientedBox:
    """A box in the world.

    Attributes:
        center: centre, shape (3,) [m].
        R: orientation (columns: the box axes in the world), shape (3, 3).
        half: half sizes along the box axes, shape (3,) [m], >= 0.
        name: for messages.
    """

    center: np.ndarray
    R: np.ndarray
    half: np.ndarray
    name: str = ""

    def __post_init__(self) -> None:
        c = np.asarray(self.center, float)
        R = np.asarray(self.R, float)
        h = np.asarray(self.half, float)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise PlanningError(f"OrientedBox {self.name!r}: center must be 3 finite numbers [m], got {c!r}")
        if R.shape != (3, 3) or np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0.0:
            raise PlanningError(f"OrientedBox {self.name!r}: R must be a rotation matrix")
        if h.shape != (3,) or not np.all(np.isfinite(h)) or np.any(h < 0.0):
            raise PlanningError(f"OrientedBox {self.name!r}: half sizes must be 3 finite numbers >= 0 [m], got {h!r}")
        object.__setattr__(self, "center", _frozen(c))
        object.__setattr__(self, "R", _frozen(R))
        object.__setattr__(self, "half", _frozen(h))

    @classmethod
    def from_box(cls, box: Box | object) -> "OrientedBox":
        """From a scene box: anything with `center`, `size` (full sizes) and `rpy` (and optionally `name`)."""
        try:
            center, size = np.asarray(box.center, float), np.asarray(box.size, float)
            rpy = np.asarray(getattr(box, "rpy", (0.0, 0.0, 0.0)), float)
        except AttributeError:
            raise PlanningError(f"a terrain box needs center, size and rpy, got {type(box).__name__}") from None
        name = str(getattr(box, "name", "") or "")
        if size.shape != (3,) or np.any(~np.isfinite(size)) or np.any(size <= 0.0):
            raise PlanningError(f"terrain box {name!r}: size must be 3 positive lengths [m], got {size.tolist()}")
        if rpy.shape != (3,) or not np.all(np.isfinite(rpy)):
            raise PlanningError(f"terrain box {name!r}: rpy must be 3 finite angles [rad], got {rpy.tolist()}")
        return cls(center, rpy_matrix(*rpy), size / 2.0, name)

    def vertices(self) -> np.ndarray:
        """The 8 corners, shape (8, 3) [m]."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
        return self.center + (signs * self.half) @ self.R.T

    def top_face(self) -> tuple[np.ndarray, np.ndarray]:
        """The face whose outward normal points most upwards: vertices (4, 3) counter-clockwise seen from
        outside, and the unit outward normal (3,)."""
        zs = self.R[2, :]
        i = int(np.argmax(np.abs(zs)))
        sign = 1.0 if zs[i] >= 0.0 else -1.0
        j, k = (i + 1) % 3, (i + 2) % 3  # (e_j x e_k) = e_i: counter-clockwise about +e_i in (j, k)
        local = []
        for a, b in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
            v = np.zeros(3)
            v[i] = sign * self.half[i]
            v[j] = a * self.half[j]
            v[k] = b * self.half[k]
            local.append(v)
        verts = self.center + np.array(local) @ self.R.T
        normal = sign * self.R[:, i]
        if sign < 0.0:
            verts = verts[::-1]
        return verts, normal


@dataclass(frozen=True, eq=False)
class ContactSurface:
    """A planar convex contact surface with its outward normal.

    Attributes:
        name: the box's name ("floor" for the floor).
        vertices: world vertices, shape (k, 3) [m], k >= 3, coplanar, counter-clockwise seen from the normal.
        normal: outward unit normal, shape (3,), pointing up (z > 0).
        box_index: index of the box in `ContactTerrain.boxes`, None for the floor.

    Derived (read-only): `R_world_surface` (3, 3) with z = normal and x the steepest-ascent-free direction
    closest to world x; `polygon` (k, 2) the vertices in the surface frame; `slope` [rad].
    """

    name: str
    vertices: np.ndarray
    normal: np.ndarray
    box_index: int | None = None
    R_world_surface: np.ndarray = field(init=False, repr=False)
    polygon: np.ndarray = field(init=False, repr=False)
    _inward: np.ndarray = field(init=False, repr=False)   # (k, 2) inward unit edge normals, surface frame
    _offset: np.ndarray = field(init=False, repr=False)   # (k,) inward . vertex

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices, float)
        n = np.asarray(self.normal, float)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3 or not np.all(np.isfinite(v)):
            raise PlanningError(f"ContactSurface {self.name!r}: vertices must be (k >= 3, 3) finite [m]")
        norm = np.linalg.norm(n)
        if n.shape != (3,) or not np.isfinite(norm) or norm < 1e-9:
            raise PlanningError(f"ContactSurface {self.name!r}: normal must be a non-zero 3-vector")
        n = n / norm
        if n[2] <= 1e-6:
            raise PlanningError(f"ContactSurface {self.name!r}: the normal must point up, got {n.tolist()}")
        off_plane = np.abs((v - v[0]) @ n).max()
        if off_plane > 1e-6:
            raise PlanningError(f"ContactSurface {self.name!r}: vertices are not coplanar ({off_plane:.2e} m off)")
        x = np.array([1.0, 0.0, 0.0]) - n[0] * n
        if np.linalg.norm(x) < 1e-6:
            x = np.array([0.0, 1.0, 0.0]) - n[1] * n
        x /= np.linalg.norm(x)
        R = np.column_stack([x, np.cross(n, x), n])
        poly = (v - v[0]) @ R[:, :2]
        edges = np.roll(poly, -1, axis=0) - poly
        lengths = np.linalg.norm(edges, axis=1)
        if np.any(lengths < 1e-9):
            raise PlanningError(f"ContactSurface {self.name!r}: repeated vertices")
        inward = np.column_stack([-edges[:, 1], edges[:, 0]]) / lengths[:, None]
        cross = edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1)
        if np.any(cross <= 1e-12):
            raise PlanningError(f"ContactSurface {self.name!r}: the polygon must be convex and counter-clockwise "
                             "seen from the normal")
        object.__setattr__(self, "vertices", _frozen(v))
        object.__setattr__(self, "normal", _frozen(n))
        object.__setattr__(self, "R_world_surface", _frozen(R))
        object.__setattr__(self, "polygon", _frozen(poly))
        object.__setattr__(self, "_inward", _frozen(inward))
        object.__setattr__(self, "_offset", _frozen(np.sum(inward * poly, axis=1)))

    @property
    def slope(self) -> float:
        """Angle between the normal and the world vertical [rad]."""
        return float(np.arccos(np.clip(self.normal[2], -1.0, 1.0)))

    @property
    def point(self) -> np.ndarray:
        """A point of the plane (the first vertex), shape (3,) [m]."""
        return self.vertices[0]

    def height_at(self, xy: np.ndarray) -> np.ndarray:
        """Height of the plane above the world point(s) xy, shape (..., 2) -> (...) [m]."""
        xy = np.asarray(xy, float)
        p0, n = self.vertices[0], self.normal
        return p0[2] - (n[0] * (xy[..., 0] - p0[0]) + n[1] * (xy[..., 1] - p0[1])) / n[2]

    def margin(self, points: np.ndarray) -> np.ndarray:
        """Signed in-plane distance of points to the polygon boundary [m], > 0 inside.

        The points (shape (..., 3), world) are projected on the plane along the normal.
        Returns shape (...).
        """
        p = np.asarray(points, float)
        local = (p - self.vertices[0]) @ self.R_world_surface[:, :2]
        return np.min(local @ self._inward.T - self._offset, axis=-1)

    def distance_to_plane(self, points: np.ndarray) -> np.ndarray:
        """Signed distance of world points (..., 3) to the plane along the normal [m] (> 0 above)."""
        return (np.asarray(points, float) - self.vertices[0]) @ self.normal

    def contains_xy(self, xy: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Whether the vertical projection of xy (..., 2) on the plane lies in the polygon with `margin`."""
        xy = np.asarray(xy, float)
        p = np.concatenate([xy, self.height_at(xy)[..., None]], axis=-1)
        return self.margin(p) >= margin

    def foot_rotation(self, yaw: float | np.ndarray) -> np.ndarray:
        """Sole orientation on this surface: z = the normal, x the heading `yaw` [rad] projected on the plane.

        Shape (3, 3), or (n, 3, 3) for an array of n yaws.
        """
        yaw = np.asarray(yaw, float)
        h = np.stack([np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)], axis=-1)
        n = self.normal
        x = h - (h @ n)[..., None] * n
        x /= np.linalg.norm(x, axis=-1, keepdims=True)
        y = np.cross(n, x)
        zcol = np.broadcast_to(n, x.shape)
        return np.stack([x, y, zcol], axis=-1)

    def footprint_margin(self, p_world_sole: np.ndarray, R_world_sole: np.ndarray, sole: SoleRectangle) -> float:
        """Smallest in-plane distance from the sole rectangle's corners to the polygon boundary [m] (> 0 inside)."""
        corners = np.asarray(p_world_sole, float) + sole.corners_in_sole() @ np.asarray(R_world_sole, float).T
        return float(self.margin(corners).min())


def sole_box(p_world_sole: np.ndarray, R_world_sole: np.ndarray, sole: SoleRectangle,
             thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """The sole box: the sole rectangle extruded by `thickness` [m] along the sole z axis (as the simulator's
    sole geom). Returns its centre(s) (..., 3) and half sizes (3,)."""
    p = np.asarray(p_world_sole, float)
    R = np.asarray(R_world_sole, float)
    local = np.array([sole.center_x, sole.center_y, 0.5 * thickness])
    center = p + np.einsum("...ij,j->...i", R, local)
    return center, np.array([0.5 * sole.length, 0.5 * sole.width, 0.5 * thickness])


def _obb_penetration(cA: np.ndarray, RA: np.ndarray, hA: np.ndarray,
                     cB: np.ndarray, RB: np.ndarray, hB: np.ndarray) -> np.ndarray:
    """Penetration depth of boxes A (n of them) against boxes B (m of them) by the separating-axis test.

    Shapes: cA (n, 3), RA (n, 3, 3), hA (3,); cB (m, 3), RB (m, 3, 3), hB (m, 3). Returns (n, m): the
    smallest overlap of the projections over the 15 candidate axes, > 0 when the boxes intersect; pairs whose
    bounding spheres are apart get minus the gap between the spheres instead. For separated boxes the magnitude
    is a lower bound of their distance.
    """
    gap = np.linalg.norm(cB[None, :, :] - cA[:, None, :], axis=-1) - np.linalg.norm(hA) - np.linalg.norm(hB, axis=1)
    out = -gap
    ia, ib = np.nonzero(gap <= 1e-6)
    if len(ia) == 0:
        return out
    axA = np.swapaxes(RA, 1, 2)[ia]                   # (P, 3, 3): rows are A's axes
    axB = np.swapaxes(RB, 1, 2)[ib]                   # (P, 3, 3)
    cross = np.cross(axA[:, :, None, :], axB[:, None, :, :]).reshape(-1, 9, 3)
    axes = np.concatenate([axA, axB, cross], axis=1)  # (P, 15, 3)
    norms = np.linalg.norm(axes, axis=-1)
    valid = norms > 1e-9
    axes = axes / np.where(valid, norms, 1.0)[..., None]
    rA = np.abs(axes @ np.swapaxes(axA, 1, 2)) @ hA                        # (P, 15)
    rB = np.einsum("pki,pi->pk", np.abs(axes @ np.swapaxes(axB, 1, 2)), hB[ib])
    d = np.abs(np.einsum("pkd,pd->pk", axes, cB[ib] - cA[ia]))
    overlap = np.where(valid, rA + rB - d, np.inf).min(axis=-1)
    out[ia, ib] = overlap
    return out


@dataclass(frozen=True, eq=False)
class ContactTerrain:
    """The terrain as the planner sees it: oriented boxes, the floor, and the contact surfaces.

    Attributes:
        boxes: the scene's boxes.
        surfaces: the contact surfaces, the floor first (if any), then one per box with a walkable top face,
            in box order.
        floor: whether the plane z = 0 is part of the terrain.
        friction: the scene's friction coefficient (for information; the centroidal planner takes its own mu).
    """

    boxes: tuple[OrientedBox, ...]
    surfaces: tuple[ContactSurface, ...]
    floor: bool = True
    friction: float = 1.0
    _centers: np.ndarray = field(init=False, repr=False)
    _Rs: np.ndarray = field(init=False, repr=False)
    _halves: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        boxes = tuple(self.boxes)
        object.__setattr__(self, "boxes", boxes)
        object.__setattr__(self, "surfaces", tuple(self.surfaces))
        if not self.surfaces:
            raise PlanningError("ContactTerrain: no contact surface (no floor and no box with a walkable top)")
        object.__setattr__(self, "_centers", _frozen(np.array([b.center for b in boxes]).reshape(-1, 3)))
        object.__setattr__(self, "_Rs", _frozen(np.array([b.R for b in boxes]).reshape(-1, 3, 3)))
        object.__setattr__(self, "_halves", _frozen(np.array([b.half for b in boxes]).reshape(-1, 3)))

    @classmethod
    def from_boxes(cls, boxes: Iterable[Box | OrientedBox], *, floor: bool = True, friction: float = 1.0,
                   max_slope: float = np.deg2rad(40.0), floor_extent: float = 50.0) -> "ContactTerrain":
        """Build from scene boxes (`wbcbench.scene.Box`, or anything with center, size, rpy).

        Args:
            boxes: the boxes; unnamed ones are called box_<i>.
            floor: include the plane z = 0.
            friction: the scene's friction coefficient.
            max_slope: a top face steeper than this [rad] gives no contact surface.
            floor_extent: half side of the square representing the floor [m].
        """
        obbs = []
        for i, b in enumerate(boxes):
            obb = b if isinstance(b, OrientedBox) else OrientedBox.from_box(b)
            if not obb.name:
                obb = OrientedBox(obb.center, obb.R, obb.half, f"box_{i}")
            obbs.append(obb)
        names = [b.name for b in obbs]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise PlanningError(f"terrain box names must be unique, repeated: {dup}")
        if "floor" in names:
            raise PlanningError("'floor' is reserved for the floor surface; rename the box")
        if not 0.0 < max_slope < 0.5 * np.pi:
            raise PlanningError(f"max_slope must be in (0, pi/2) rad, got {max_slope!r}")
        surfaces = []
        if floor:
            e = float(floor_extent)
            surfaces.append(ContactSurface("floor", np.array([[e, e, 0.0], [-e, e, 0.0], [-e, -e, 0.0],
                                                              [e, -e, 0.0]]), np.array([0.0, 0.0, 1.0])))
        for i, obb in enumerate(obbs):
            verts, normal = obb.top_face()
            if normal[2] >= np.cos(max_slope):
                surfaces.append(ContactSurface(obb.name, verts, normal, i))
        return cls(tuple(obbs), tuple(surfaces), bool(floor), float(friction))

    @classmethod
    def from_terrain(cls, terrain: Terrain, **kwargs: float) -> "ContactTerrain":
        """From the simulator's `Terrain` (same floor, boxes and friction); kwargs as `from_boxes`."""
        return cls.from_boxes(terrain.boxes, floor=terrain.floor, friction=terrain.friction, **kwargs)

    def surface(self, name: str) -> ContactSurface:
        """The surface called `name`; a ValueError listing the names otherwise."""
        for s in self.surfaces:
            if s.name == name:
                return s
        raise PlanningError(f"no contact surface {name!r}; surfaces: {', '.join(s.name for s in self.surfaces)}")

    def height_at(self, xy: np.ndarray) -> float:
        """Height of the highest surface whose polygon covers the point xy [m]; -inf if none."""
        xy = np.asarray(xy, float)[:2]
        heights = [float(s.height_at(xy)) for s in self.surfaces if s.contains_xy(xy)]
        return max(heights) if heights else -np.inf

    def penetration(self, centers: np.ndarray, R: np.ndarray, half: np.ndarray) -> np.ndarray:
        """Largest penetration depth of box(es) into the terrain (any box or the floor) [m].

        Args:
            centers: (n, 3) or (3,) box centres [m].
            R: (n, 3, 3) or (3, 3) orientations.
            half: (3,) half sizes [m], common to all.

        Returns:
            (n,) or scalar: > 0 where the box intersects the terrain, <= 0 where it is free (or only touches);
            for a free box the magnitude is a lower bound of its distance to the terrain.
        """
        scalar = np.ndim(centers) == 1
        c = np.atleast_2d(np.asarray(centers, float))
        Rs = np.asarray(R, float).reshape(-1, 3, 3)
        Rs = np.broadcast_to(Rs, (len(c), 3, 3))
        h = np.asarray(half, float)
        depth = np.full(len(c), -np.inf)
        if self.floor:
            signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
            z = c[:, None, 2] + np.einsum("nj,kj->nk", Rs[:, 2, :], signs * h)
            depth = np.maximum(depth, -z.min(axis=1))
        if len(self.boxes):
            depth = np.maximum(depth, _obb_penetration(c, Rs, h, self._centers, self._Rs, self._halves).max(axis=1))
        return float(depth[0]) if scalar else depth

    def sole_penetration(self, p_world_sole: np.ndarray, R_world_sole: np.ndarray, sole: SoleRectangle,
                         thickness: float = 0.02) -> np.ndarray:
        """Penetration depth of the sole box (the sole rectangle extruded by `thickness` [m] upwards along
        the sole normal) into the terrain [m]; shapes (3,)/(3, 3) -> scalar, (n, 3)/(n, 3, 3) -> (n,)."""
        if not np.isfinite(thickness) or thickness < 0.0:
            raise PlanningError(f"sole thickness must be >= 0 [m], got {thickness!r}")
        centers, half = sole_box(p_world_sole, R_world_sole, sole, thickness)
        return self.penetration(centers, R_world_sole, half)


# ---- the scenario geometries ---------------------------------------------------------------------------

def stairs_boxes(count: int = 6, height: float = 0.10, depth: float = 0.30, width: float = 1.0,
                 start_x: float = 0.3) -> tuple[Box, ...]:
    """Stairs going up along +x (paper 000, Section 6.4: 6 steps, 10 cm high, 30 cm deep).

    Exactly `wbcbench.scene.stairs` (YAML: `terrain: {type: stairs, count: 6, height: 0.1, depth: 0.3,
    width: 1.0, start_x: 0.3}`): step i (1-based) is a block from the floor to z = i * height, its tread
    covering x in [start_x + (i - 1) depth, start_x + i depth], y in [-width / 2, width / 2].
    """
    if int(count) != count or count < 1:
        raise PlanningError(f"stairs count must be a positive integer, got {count!r}")
    for name, value in (("height", height), ("depth", depth), ("width", width)):
        if not np.isfinite(value) or value <= 0.0:
            raise PlanningError(f"stairs {name} must be a positive length [m], got {value!r}")
    return stairs(int(count), float(height), float(depth), float(width), float(start_x))


def platform_boxes(slope_deg: float = 15.0, count: int = 6, depth: float = 0.30, width: float = 1.0,
                   start_x: float = 0.15, thickness: float = 0.10) -> tuple[Box, ...]:
    """Tilted platforms: `count` boxes in a row along +x, pitched alternately up and down (a zigzag).

    Platform i (0-based) covers x in [start_x + i depth, start_x + (i + 1) depth] (horizontal projection of its
    top), y in [-width / 2, width / 2]. Its top face is a plane inclined by `slope_deg` about the y axis, rising
    along +x for even i (normal leaning to -x) and falling for odd i, from z = 0 to the ridge height
    depth * tan(slope) and back: valleys at z = 0 (the first at start_x, flush with the floor), ridges at
    z = depth tan(slope). `count` must be even so that the walk ends on the floor. Each box is `thickness` thick
    (perpendicular to its top) and extends below the floor (the floor plane hides that part).

    Defaults (the scenario "platforms"): 15 degrees, 6 platforms of 0.30 m x 1.0 m from x = 0.15 to 1.95,
    ridges 0.0804 m high. With TALOS's feet starting centred at x = 0 and 0.30 m steps, the footholds are the
    platform centres x = 0.30, 0.60, ..., 1.80: in every double support on the platforms one foot stands on a
    rising and the other on a falling slope (opposite pitch, 30 degrees apart), and every single support is on
    a 15 degree slope. Box i: centre (start_x + (i + 0.5) depth - s t/2 sin(a), 0, h_i - t/2 cos(a)) with
    h_i = depth tan(a) / 2 the top centre height, a = slope, s = +1 rising / -1 falling, size
    (depth / cos(a), width, t), rpy (0, -s a, 0).

    Returns:
        the boxes, named platform_1 ... platform_<count>.
    """
    a = np.deg2rad(float(slope_deg))
    if not 0.0 < a < np.deg2rad(45.0):
        raise PlanningError(f"platform slope must be in (0, 45) degrees, got {slope_deg!r}")
    if int(count) != count or count < 2 or count % 2:
        raise PlanningError(f"platform count must be a positive even integer (the walk ends on the floor), got "
                         f"{count!r}")
    for name, value in (("depth", depth), ("width", width), ("thickness", thickness)):
        if not np.isfinite(value) or value <= 0.0:
            raise PlanningError(f"platform {name} must be a positive length [m], got {value!r}")
    boxes = []
    h_top = 0.5 * depth * np.tan(a)  # height of the top face's centre
    for i in range(int(count)):
        s = 1.0 if i % 2 == 0 else -1.0  # rising / falling along +x
        pitch = -s * a                   # Ry(pitch) tilts the box's +x end up for pitch < 0
        # the top-face centre, then back along the top normal by half the thickness
        top_center = np.array([start_x + (i + 0.5) * depth, 0.0, h_top])
        normal = np.array([-s * np.sin(a), 0.0, np.cos(a)])
        center = top_center - 0.5 * thickness * normal
        boxes.append(Box(center=tuple(float(v) for v in np.round(center, 12)),
                         size=(float(depth / np.cos(a)), float(width), float(thickness)),
                         rpy=(0.0, float(pitch), 0.0), name=f"platform_{i + 1}"))
    return tuple(boxes)


def boxes_to_yaml(boxes: Sequence[Box], *, floor: bool = True, friction: float | None = None) -> dict:
    """The `terrain:` mapping of a scenario file for these boxes (type: boxes), plain Python values."""
    out: dict = {"type": "boxes", "floor": bool(floor)}
    if friction is not None:
        out["friction"] = float(friction)
    out["boxes"] = [{"name": b.name, "center": [round(float(v), 6) for v in b.center],
                     "size": [round(float(v), 6) for v in b.size],
                     "rpy": [round(float(v), 6) for v in b.rpy]} for b in boxes]
    return out
