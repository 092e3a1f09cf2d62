"""Self-collision keys of a robot profile derived from the model's collision geometry (`robot init`).

* `collision_check`, per side: the effector is every link of the hand's subtree (from the hand frame's parent joint
  down; from the nearest joint above it whose subtree has collision geometry when the hand's own has none), the bodies every other link that is not on that arm's chain (from below the torso joint to the hand):
  base, torso, head, legs and the whole other arm. Links are named as MuJoCo builds them: a link fixed to its
  parent (fused into it, `fusestatic`) is represented by the moving link it hangs from, so its geometry is counted
  under that name; links without collision geometry (own or fused) are left out.
* `repulsors`, per side: the protected point is the centre of the bounding box of the hand subtree's collision
  points (in the hand frame, at the standing posture), its radius the largest distance from it to those points;
  the repulsion spheres bound the collision points of the other arm's forearm and hand (the links whose joint is
  at least 40 % of the way from the shoulder to the wrist), of the torso link and of the base link: per link, the
  points are split into up to 3 equal slabs along their principal axis (a long link gets a few spheres, as TALOS'
  hand-written forearm has), each slab bounded by a sphere. A sphere that already overlaps the protected point's
  reach at the standing posture (d < 1.4 (r_frame + r_rep): C = exp(-(d / a)^3) above 0.06, the value TALOS' thigh
  radius was chosen under) is left out: it would push the hand away from where it stands.

Collision points: a mesh's vertices, a box's corners, points on a sphere's, cylinder's or capsule's surface.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

__all__ = ["SelfCollisionKeys", "collision_points", "fit_spheres", "self_collision_keys", "self_collision_yaml"]

#: the protected point's reach above which a repulsion sphere is dropped, in units of r_frame + r_rep (module doc)
REST_CLEARANCE = 1.4
#: at most this many spheres per link
MAX_SPHERES = 3
#: a joint this share of the shoulder-wrist distance out, or further, carries the forearm
FOREARM_FROM = 0.4


def _unit_sphere(n: int = 6) -> np.ndarray:
    th, ph = np.meshgrid(np.linspace(0, np.pi, n + 1), np.linspace(0, 2 * np.pi, 2 * n, endpoint=False))
    return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1).reshape(-1, 3)


def collision_points(geom: pin.GeometryObject) -> np.ndarray:
    """Points (k, 3) of one collision geometry, in its parent joint's frame (module docstring)."""
    g = geom.geometry
    kind = type(g).__name__
    if hasattr(g, "num_vertices") and g.num_vertices > 0:
        local = np.array([np.asarray(g.vertex(i), float) for i in range(g.num_vertices)])
    elif kind == "Box":
        h = np.asarray(g.halfSide, float)
        local = np.array([[x, y, z] for x in (-h[0], h[0]) for y in (-h[1], h[1]) for z in (-h[2], h[2])])
    elif kind == "Sphere":
        local = g.radius * _unit_sphere()
    elif kind in ("Cylinder", "Capsule"):
        ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
        ring = np.stack([g.radius * np.cos(ang), g.radius * np.sin(ang), np.zeros_like(ang)], axis=1)
        local = np.vstack([ring + [0, 0, z] for z in (-g.halfLength, g.halfLength)])
        if kind == "Capsule":
            cap = g.radius * _unit_sphere()
            local = np.vstack([local, cap + [0, 0, g.halfLength], cap - [0, 0, g.halfLength]])
    else:  # anything else: the corners of its local bounding box
        g.computeLocalAABB()
        lo, hi = np.array(g.aabb_local.min_), np.array(g.aabb_local.max_)
        local = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    M = geom.placement
    return local @ M.rotation.T + M.translation


def fit_spheres(points: np.ndarray, max_spheres: int = MAX_SPHERES) -> list[tuple[np.ndarray, float]]:
    """Spheres (centre, radius) whose union contains `points` (k, 3): the points split into up to `max_spheres`
    equal slabs along their principal axis (as many as the length over the cross-section's diameter), each slab's
    points bounded by the sphere about the centre of their bounding box."""
    mean = points.mean(axis=0)
    c = points - mean
    axis = np.linalg.svd(c, full_matrices=False)[2][0]
    t = c @ axis
    cross = np.linalg.norm(c - np.outer(t, axis), axis=1).max()
    length = t.max() - t.min()
    n = int(np.clip(round(length / max(2 * cross, 1e-6)), 1, max_spheres))
    edges = np.linspace(t.min(), t.max(), n + 1)
    out = []
    for i in range(n):
        sel = (t >= edges[i]) & (t <= edges[i + 1])
        if not sel.any():
            continue
        p = points[sel]
        centre = (p.min(axis=0) + p.max(axis=0)) / 2
        out.append((centre, float(np.linalg.norm(p - centre, axis=1).max())))
    return out


class SelfCollisionKeys:
    """The derived keys: `collision_check[side] = (effector links, body links)`, `repulsors[side] = (hand frame,
    offset, radius, [(name, link, offset, radius)])`, `dropped[side]`: repulsion spheres left out (module doc)."""

    def __init__(self) -> None:
        self.collision_check: dict[str, tuple[list[str], list[str]]] = {}
        self.repulsors: dict[str, tuple[str, np.ndarray, float, list[tuple[str, str, np.ndarray, float]]]] = {}
        self.dropped: dict[str, list[str]] = {}


def _apply(M: pin.SE3, p: np.ndarray) -> np.ndarray:
    return p @ M.rotation.T + M.translation


def _apply_inv(M: pin.SE3, p: np.ndarray) -> np.ndarray:
    return (p - M.translation) @ M.rotation


def _link_of_joint(model: pin.Model, j: int) -> int:
    """The frame id of the link a joint moves (its child link: the first body frame on it)."""
    return next(k for k, f in enumerate(model.frames) if f.type == pin.FrameType.BODY and f.parentJoint == j)


def self_collision_keys(model: pin.Model, geom: pin.GeometryModel, hands: dict[str, str], torso: str,
                        q: np.ndarray) -> SelfCollisionKeys | None:
    """The `collision_check` and `repulsors` keys (module docstring) of a model with collision geometry `geom`;
    `hands`: side ("left", "right") -> hand frame name, `torso`: the torso frame, q: the standing posture. None
    when an arm has no collision geometry."""
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    points: dict[int, np.ndarray] = {}  # joint -> its collision points (joint frame)
    for g in geom.geometryObjects:
        p = collision_points(g)
        points[g.parentJoint] = np.vstack([points[g.parentJoint], p]) if g.parentJoint in points else p
    geo_joints = sorted(j for j in points if j > 0)

    def name(j: int) -> str:
        return model.frames[_link_of_joint(model, j)].name

    torso_joint = model.frames[model.getFrameId(torso)].parentJoint
    above = set(model.supports[torso_joint])
    hand_joint = {s: model.frames[model.getFrameId(f)].parentJoint for s, f in hands.items()}
    # the hand's subtree; from the nearest joint above whose subtree has geometry when the hand's own has none
    subtree = {}
    for s, hj in hand_joint.items():
        j = next((k for k in reversed(list(model.supports[hj])) if set(model.subtrees[k]) & set(geo_joints)), hj)
        subtree[s] = set(model.subtrees[j])
    chain = {s: [j for j in model.supports[j] if j not in above] for s, j in hand_joint.items()}
    out = SelfCollisionKeys()
    for side in hands:
        other = "right" if side == "left" else "left"
        eff = [name(j) for j in geo_joints if j in subtree[side]]
        bodies = [name(j) for j in geo_joints if j not in subtree[side] and j not in chain[side]]
        out.collision_check[side] = (eff, bodies)
        # the protected point: the hand subtree's points, in the hand frame
        hf = model.getFrameId(hands[side])
        if not subtree[side] & set(geo_joints):
            return None
        pts = np.vstack([_apply(data.oMi[j], points[j]) for j in geo_joints if j in subtree[side]])
        local = _apply_inv(data.oMf[hf], pts)
        centre = (local.min(axis=0) + local.max(axis=0)) / 2
        r_frame = float(np.linalg.norm(local - centre, axis=1).max())
        protected = data.oMf[hf].act(centre)
        # the repulsion spheres: the other forearm and hand, the torso, the base
        ch = chain[other]
        shoulder = data.oMi[ch[0]].translation
        reach = np.linalg.norm(data.oMi[hand_joint[other]].translation - shoulder)
        forearm = [j for j in ch if np.linalg.norm(data.oMi[j].translation - shoulder) >= FOREARM_FROM * reach]
        sources = [j for j in geo_joints if j in subtree[other] or j in forearm]
        for j in (torso_joint, 1):
            if j in points and j not in sources:
                sources.append(j)
        spheres, dropped = [], []
        for j in sources:
            fid = _link_of_joint(model, j)
            link = model.frames[fid].name
            for k, (c, r) in enumerate(fit_spheres(points[j])):
                label = f"{link}_{k}"
                d = np.linalg.norm(data.oMi[j].act(c) - protected)
                if d < REST_CLEARANCE * (r + r_frame):
                    dropped.append(label)
                    continue
                spheres.append((label, link, model.frames[fid].placement.actInv(c), r))
        out.repulsors[side] = (hands[side], centre, r_frame, spheres)
        out.dropped[side] = dropped
    return out


def _vec(v) -> str:
    return "[" + ", ".join(f"{x:.4f}" for x in v) + "]"


def _names(names: list[str], indent: str) -> list[str]:
    lines, line = [], ""
    for n in names:
        if line and len(line) + len(n) + 2 > 100:
            lines.append(line + ",")
            line = ""
        line = f"{line}, {n}" if line else n
    lines.append(line)
    pad = " " * len(indent)
    return [(indent + "[" if i == 0 else pad + " ") + ln + ("]" if i == len(lines) - 1 else "")
            for i, ln in enumerate(lines)]


def self_collision_yaml(keys: SelfCollisionKeys) -> list[str]:
    """The keys as commented profile YAML lines."""
    L = ["# Self-collision repulsors (tasksets' self_collision tasks, the teleoperation command filter's body spheres)",
         "# and self-collision counting, generated from the collision geometry (wbcbench/robots/collision.py): the",
         "# protected point bounds the hand's geometry; the spheres bound the other forearm and hand, the torso and",
         "# the base; spheres already near the hand at the standing posture are left out."]
    L.append("repulsors:")
    for side, (frame, offset, radius, spheres) in keys.repulsors.items():
        L += [f"  {side}:", f"    frame: {frame}", f"    offset: {_vec(offset)}", f"    radius: {radius:.4f}",
              "    exponent: 3.0", "    normalized: true"]
        if keys.dropped.get(side):
            L.append(f"    # left out (near the hand at the standing posture): {', '.join(keys.dropped[side])}")
        L.append("    points:")
        for label, link, off, r in spheres:
            L.append(f"      - {{name: {label}, frame: {link}, offset: {_vec(off)}, radius: {r:.4f}}}")
    L.append("collision_check:                   # the hand's subtree against the links off its arm's chain")
    for side, (eff, bodies) in keys.collision_check.items():
        L += [f"  {side}:", *_names(eff, "    effector: "), *_names(bodies, "    bodies: ")]
    return L
