"""Contact planner: foot placements on the contact surfaces of a terrain, from a start to a goal.

Search: greedy forward placement with depth-first backtracking. Feet alternate (`first_side` first). For the
moving foot, candidate placements are a lattice (`grid`, default 1 cm) of offsets from the stance foot in the
heading frame (forward offset in [-max_backward, max_step_length], lateral offset in [min_width, max_width] on
the foot's own side), plus the foot's goal position when it is within reach. A candidate is feasible when

- a contact surface holds it: the sole frame lies on the surface plane above the candidate's x-y, its z axis
  is the surface normal and its x axis the heading projected on the plane, and the whole sole rectangle is
  inside the surface polygon by at least `margin` (in the plane);
- the sole box (the rectangle extruded by `sole_thickness` along the normal, as the simulator's sole geom),
  grown by `clearance` in its plane, penetrates no terrain box and not the floor (it rests on its own support);
- its height differs from the stance foot's by at most `max_step_height`, and its footprint does not overlap
  the stance footprint;
- it brings the foot at least `min_progress` closer to its goal position (the goal x-y offset by half the
  foot separation to the foot's side), or it is that goal position.

Feasible candidates are tried best first, the score being the distance to the foot's goal position minus
`margin_bonus` times the footprint margin (capped at `margin_cap`), plus 1e-3 times the deviation from the
nominal foot separation: the farthest placement, traded for a foothold away from the surface border (on 30 cm
treads the foot goes to the tread centre rather than 2 cm from its edge). If a branch dead-ends the search
backtracks to the next candidate. States already visited are skipped; `max_checks`
bounds the number of candidate evaluations. The heading (the feet's yaw) is the start feet's and is kept: the
planner does not turn.

Before searching, two checks give a clear ValueError:
- goal off the terrain: the goal feet positions are not feasible footholds;
- no reachable next surface: the surfaces are sampled (`graph_grid`) for feasible footholds within a band of
  half width `graph_corridor` around the straight start-goal line, two samples are linked when one is within a
  step (forward, lateral, height limits) of the other, and the goal feet must be in a connected component of
  the start feet. This is a necessary condition for the search (every new foothold is within a step of the
  stance foot, and the search does not detour), so gaps, walls and steps too high are reported at once, naming
  the last reachable surface and the next one ahead.

Explicit placements are also accepted (`contacts_from_placements`): each is projected on (or checked against)
the surfaces with the same rules.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import PlanningError
from .footsteps import Footstep, FootstepPlan, ReachLimits, StepTiming
from .geometry import SoleRectangle, polygons_penetration, yaw_of
from .terrain import ContactSurface, ContactTerrain, sole_box
from ..side import Side

__all__ = ["ContactPlannerConfig", "Foothold", "ContactPlan", "find_foothold", "locate_foot", "plan_contacts",
           "contacts_from_placements"]


def _positive(name: str, value: float) -> None:
    if not isinstance(value, (int, float, np.integer, np.floating)) or not np.isfinite(value) or value <= 0.0:
        raise PlanningError(f"ContactPlannerConfig.{name} must be positive, got {value!r}")


@dataclass(frozen=True)
class ContactPlannerConfig:
    """Limits and search settings of the contact planner (lengths in m).

    Attributes:
        max_step_length: |forward offset| of the new foot from the stance foot, horizontal, along the heading.
        max_backward: largest backward offset the search tries (<= max_step_length).
        max_step_height: |height difference| between the new foot and the stance foot (sole origins).
        foot_separation: nominal lateral offset between the feet (TALOS: 0.17); also the goal stance width.
        min_width, max_width: range of the lateral offset of the new foot from the stance foot.
        margin: the sole rectangle stays this far inside the surface polygon (in the plane).
        sole_thickness: height of the sole box checked against the terrain.
        clearance: the sole box, grown by this much in its plane, must not touch any box but its support
            (e.g. keeps the toe 2 cm off a stair riser).
        grid: lattice step of the candidate offsets.
        min_progress: a step must bring the foot this much closer to its goal position.
        margin_bonus, margin_cap: ranking of candidates: distance to the goal position minus
            margin_bonus * min(footprint margin, margin_cap).
        max_goal_bearing: the goal must lie within this angle [rad] of the start heading (the planner keeps the
            heading and does not turn); goals closer than max_step_length are exempt.
        first_side: the foot that moves first.
        max_checks: budget of candidate evaluations for the search.
        graph_grid: sampling step of the surfaces for the reachability check.
        graph_corridor: half width of the band around the straight start-goal line in which the reachability
            check samples footholds (the search does not detour either).
    """

    max_step_length: float = 0.30
    max_backward: float = 0.10
    max_step_height: float = 0.15
    foot_separation: float = 0.17
    min_width: float = 0.15
    max_width: float = 0.25
    margin: float = 0.02
    sole_thickness: float = 0.02
    clearance: float = 0.02
    grid: float = 0.01
    min_progress: float = 0.005
    margin_bonus: float = 1.5
    margin_cap: float = 0.05
    max_goal_bearing: float = np.deg2rad(45.0)
    first_side: Side = Side.RIGHT
    max_checks: int = 30_000
    graph_grid: float = 0.025
    graph_corridor: float = 0.35

    def __post_init__(self) -> None:
        for name in ("max_step_length", "max_step_height", "foot_separation", "min_width", "max_width", "grid",
                     "min_progress", "graph_grid", "graph_corridor"):
            _positive(name, getattr(self, name))
        for name in ("max_backward", "margin", "sole_thickness", "clearance", "margin_bonus", "margin_cap"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0.0:
                raise PlanningError(f"ContactPlannerConfig.{name} must be >= 0, got {v!r}")
        if not 0.0 < self.max_goal_bearing <= np.pi:
            raise PlanningError(f"ContactPlannerConfig.max_goal_bearing must be in (0, pi] rad, got "
                             f"{self.max_goal_bearing!r}")
        if self.max_backward > self.max_step_length:
            raise PlanningError("ContactPlannerConfig.max_backward must not exceed max_step_length")
        if not self.min_width <= self.foot_separation <= self.max_width:
            raise PlanningError(f"ContactPlannerConfig: need min_width <= foot_separation <= max_width, got "
                             f"{self.min_width}, {self.foot_separation}, {self.max_width}")
        object.__setattr__(self, "first_side", Side.parse(self.first_side))
        if int(self.max_checks) != self.max_checks or self.max_checks < 1:
            raise PlanningError(f"ContactPlannerConfig.max_checks must be a positive integer, got {self.max_checks!r}")

    def reach_limits(self) -> ReachLimits:
        """Limits for `FootstepPlan`'s own validation, which measures offsets in the (possibly tilted) stance
        sole frame: bounded by the norm of the horizontal-frame limits."""
        r = float(np.hypot(self.max_step_length, self.max_step_height))
        w = float(np.hypot(self.max_width, self.max_step_height))
        return ReachLimits(max_length=r + 1e-6, max_width=w + 1e-6, max_height=r + 1e-6, max_yaw=0.8)


@dataclass(frozen=True, eq=False)
class Foothold:
    """A foot placed on a contact surface.

    Attributes:
        footstep: the sole pose.
        surface: the surface it stands on.
        margin: smallest in-plane distance of the sole corners to the surface border [m].
    """

    footstep: Footstep
    surface: ContactSurface
    margin: float


@dataclass(frozen=True, eq=False)
class ContactPlan:
    """A footstep plan on a terrain.

    Attributes:
        footsteps: the plan (initial feet, steps, timing, sole).
        initial_surfaces: Side -> the surface each start foot stands on.
        surfaces: the surface of each step, in step order.
        margins: the footprint margin of each step [m].
        method: "greedy-dfs" (found by the search) or "explicit" (placements given).
        terrain: the terrain it was planned on.
        config: the planner settings.
    """

    footsteps: FootstepPlan
    initial_surfaces: Mapping[Side, ContactSurface]
    surfaces: tuple[ContactSurface, ...]
    margins: tuple[float, ...]
    method: str
    terrain: ContactTerrain
    config: ContactPlannerConfig

    def __post_init__(self) -> None:
        object.__setattr__(self, "initial_surfaces", MappingProxyType(dict(self.initial_surfaces)))

    @property
    def n_steps(self) -> int:
        return self.footsteps.n_steps

    def surfaces_before(self, i: int) -> dict[Side, ContactSurface]:
        """The surface under each foot just before step i (i = n_steps: at the end)."""
        out = dict(self.initial_surfaces)
        for k in range(i):
            out[self.footsteps.steps[k].side] = self.surfaces[k]
        return out


# ---- footholds --------------------------------------------------------------------------------------------

def _heading_axes(yaw: float) -> tuple[np.ndarray, np.ndarray]:
    return np.array([np.cos(yaw), np.sin(yaw)]), np.array([-np.sin(yaw), np.cos(yaw)])


def _sole_free(terrain: ContactTerrain, p: np.ndarray, R: np.ndarray, normal: np.ndarray, sole: SoleRectangle,
               thickness: float, clearance: float) -> np.ndarray:
    """Whether soles at p (n, 3), R (n, 3, 3) standing on a surface of this normal keep off the terrain: the sole
    box, grown by `clearance` in its plane and lifted 0.1 mm off its support, penetrates nothing. Shape (n,)."""
    c, half = sole_box(p + 1e-4 * normal, R, sole, thickness)
    half = half + np.array([clearance, clearance, 0.0])
    return terrain.penetration(c, R, half) <= 1e-6


def _on_surface(terrain: ContactTerrain, k: int, xy: np.ndarray, yaw: float, sole: SoleRectangle, margin: float,
                thickness: float, clearance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Feasibility of footholds on surface k at points xy (n, 2): (ok (n,), z (n,), footprint margin (n,))."""
    s = terrain.surfaces[k]
    R = s.foot_rotation(yaw)
    z = s.height_at(xy)
    p = np.column_stack([xy, z])
    corners = p[:, None, :] + sole.corners_in_sole() @ R.T
    m = s.margin(corners).min(axis=1)
    ok = m >= margin - 1e-9
    if np.any(ok):
        idx = np.flatnonzero(ok)
        free = _sole_free(terrain, p[idx], np.broadcast_to(R, (len(idx), 3, 3)), s.normal, sole, thickness,
                          clearance)
        ok[idx[~free]] = False
    return ok, z, m


def _evaluate(terrain: ContactTerrain, xy: np.ndarray, yaw: float, sole: SoleRectangle, margin: float,
              thickness: float, clearance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Best (highest) feasible surface per point: surface index (-1: none), z, footprint margin, each (n,)."""
    n = len(xy)
    best = np.full(n, -1)
    zbest = np.full(n, -np.inf)
    mbest = np.full(n, -np.inf)
    for k, s in enumerate(terrain.surfaces):
        inside = s.contains_xy(xy, margin=0.0)
        if not np.any(inside):
            continue
        idx = np.flatnonzero(inside)
        ok, z, m = _on_surface(terrain, k, xy[idx], yaw, sole, margin, thickness, clearance)
        better = ok & (z > zbest[idx])
        best[idx[better]] = k
        zbest[idx[better]] = z[better]
        mbest[idx[better]] = m[better]
    return best, zbest, mbest


def _make_foothold(terrain: ContactTerrain, side: Side, xy: np.ndarray, k: int, yaw: float,
                   margin: float) -> Foothold:
    s = terrain.surfaces[k]
    p = np.array([xy[0], xy[1], float(s.height_at(xy))])
    return Foothold(Footstep(side, p, s.foot_rotation(yaw)), s, float(margin))


def find_foothold(terrain: ContactTerrain, side: Side, xy: Sequence[float], yaw: float, sole: SoleRectangle, *,
                  margin: float = 0.02, sole_thickness: float = 0.02, clearance: float = 0.02) -> Foothold | None:
    """The foothold of a foot whose sole origin is above `xy` [m], heading `yaw` [rad], on the highest surface
    that holds the whole sole `margin` inside and where the sole box, grown by `clearance` in its plane, is
    free of the terrain; None if there is none."""
    p = np.asarray(xy, float).reshape(1, 2)
    best, _, m = _evaluate(terrain, p, float(yaw), sole, margin, sole_thickness, clearance)
    if best[0] < 0:
        return None
    return _make_foothold(terrain, Side.parse(side), p[0], int(best[0]), float(yaw), m[0])


def locate_foot(terrain: ContactTerrain, foot: Footstep, sole: SoleRectangle, *, tolerance: float = 5e-3,
                angle_tolerance: float = np.deg2rad(3.0)) -> ContactSurface:
    """The surface a given foot stands on: its sole origin within `tolerance` [m] of the plane, its normal
    within `angle_tolerance` [rad] of the surface normal, its rectangle inside the polygon (margin >= -tolerance).

    Raises:
        ValueError: no surface holds the foot (the message names the closest one).
    """
    best, best_err = None, np.inf
    for s in terrain.surfaces:
        dist = abs(float(s.distance_to_plane(foot.p_world_sole)))
        angle = float(np.arccos(np.clip(foot.R_world_sole[:, 2] @ s.normal, -1.0, 1.0)))
        m = s.footprint_margin(foot.p_world_sole, foot.R_world_sole, sole)
        if dist <= tolerance and angle <= angle_tolerance and m >= -tolerance:
            return s
        err = dist + max(0.0, -m) + angle
        if err < best_err:
            best, best_err = (s, dist, angle, m), err
    p = foot.p_world_sole
    msg = f"the {foot.side} foot at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m is not on any contact surface"
    if best is not None:
        s, dist, angle, m = best
        msg += (f" (closest: {s.name!r}, {dist:.4f} m from its plane, normal {np.rad2deg(angle):.1f} deg off, "
                f"sole {'inside' if m >= 0 else 'outside'} by {abs(m):.3f} m)")
    raise PlanningError(msg)


# ---- reachability between surfaces ------------------------------------------------------------------------

def _check_reachable(terrain: ContactTerrain, yaw: float, sole: SoleRectangle, cfg: ContactPlannerConfig,
                     start: Mapping[Side, Foothold], goal: Mapping[Side, Foothold]) -> None:
    """Raise "no reachable next surface" when no chain of footholds, each within a step of the previous one,
    links the start feet to the goal feet inside the corridor around the straight start-goal line."""
    s_mid = np.mean([f.footstep.p_world_sole[:2] for f in start.values()], axis=0)
    g_mid = np.mean([f.footstep.p_world_sole[:2] for f in goal.values()], axis=0)
    length = float(np.linalg.norm(g_mid - s_mid))
    d = (g_mid - s_mid) / length if length > 1e-9 else _heading_axes(yaw)[0]
    dperp = np.array([-d[1], d[0]])
    back = cfg.max_step_length
    band = np.array([s_mid + u * d + v * cfg.graph_corridor * dperp for u in (-back, length + back)
                     for v in (-1.0, 1.0)])
    lo, hi = band.min(axis=0), band.max(axis=0)
    pts, owner = [], []
    for k, surf in enumerate(terrain.surfaces):
        v = surf.vertices[:, :2]
        a, b = np.maximum(v.min(axis=0), lo), np.minimum(v.max(axis=0), hi)
        if np.any(b < a):
            continue
        xs = np.arange(a[0], b[0] + 1e-9, cfg.graph_grid)
        ys = np.arange(a[1], b[1] + 1e-9, cfg.graph_grid)
        xy = np.array(np.meshgrid(xs, ys, indexing="ij")).reshape(2, -1).T
        rel = xy - s_mid
        u, w = rel @ d, rel @ dperp
        xy = xy[(u >= -back) & (u <= length + back) & (np.abs(w) <= cfg.graph_corridor) & surf.contains_xy(xy)]
        if len(xy) == 0:
            continue
        ok, z, _ = _on_surface(terrain, k, xy, yaw, sole, cfg.margin, cfg.sole_thickness, cfg.clearance)
        pts.append(np.column_stack([xy[ok], z[ok]]))
        owner.append(np.full(int(ok.sum()), k))
    index = {surf.name: k for k, surf in enumerate(terrain.surfaces)}
    ends = [*start.values(), *goal.values()]
    pts.append(np.array([f.footstep.p_world_sole for f in ends]))
    owner.append(np.array([index[f.surface.name] for f in ends]))
    P, owner = np.vstack(pts), np.concatenate(owner)
    n_start = len(P) - len(ends)
    h, l = _heading_axes(yaw)
    scale = np.array([cfg.max_step_length, cfg.max_width, cfg.max_step_height]) + 0.5 * cfg.graph_grid
    Q = np.column_stack([P[:, :2] @ h, P[:, :2] @ l, P[:, 2]]) / scale
    pairs = cKDTree(Q).query_pairs(1.0 + 1e-9, p=np.inf, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(P), len(P)))
    _, label = connected_components(graph, directed=False)
    start_labels = set(label[n_start:n_start + len(start)].tolist())
    goal_labels = label[n_start + len(start):]
    if all(g in start_labels for g in goal_labels.tolist()):
        return
    reached = np.isin(label, list(start_labels))
    u = (P[:, :2] - s_mid) @ d
    last = int(np.flatnonzero(reached)[np.argmax(u[reached])])
    ahead = np.flatnonzero(~reached & (u > u[last]))
    last_name = terrain.surfaces[owner[last]].name
    goal_names = sorted({f.surface.name for f in goal.values()})
    msg = (f"no reachable next surface: the footholds reachable from the start end on {last_name!r}, "
           f"{u[last]:.2f} m along the way to the goal ({g_mid[0]:.3f}, {g_mid[1]:.3f}) on {goal_names}")
    if len(ahead):
        nxt = int(ahead[np.argmin(u[ahead])])
        near = np.flatnonzero(reached)
        gap = np.abs(Q[near][:, None, :] - Q[nxt][None, None, :]).max(axis=-1).min() if len(near) else np.inf
        dz = float(np.min(np.abs(P[near, 2] - P[nxt, 2])))
        msg += (f"; the next surface ahead, {terrain.surfaces[owner[nxt]].name!r}, is out of reach (at least "
                f"{u[nxt] - u[last]:.2f} m further and {dz:.2f} m higher or lower; {gap:.2f} x the step limits)")
    raise PlanningError(msg + f" (limits: max_step_length {cfg.max_step_length} m, max_width {cfg.max_width} m, "
                     f"max_step_height {cfg.max_step_height} m, margin {cfg.margin} m; searched within "
                     f"{cfg.graph_corridor} m of the straight line: the planner does not detour)")


# ---- search -------------------------------------------------------------------------------------------------

def _goal_footholds(terrain: ContactTerrain, goal: np.ndarray, yaw: float, sole: SoleRectangle,
                    cfg: ContactPlannerConfig) -> dict[Side, Foothold]:
    _, l = _heading_axes(yaw)
    out = {}
    for side in (Side.LEFT, Side.RIGHT):
        xy = goal + side.sign * 0.5 * cfg.foot_separation * l
        f = find_foothold(terrain, side, xy, yaw, sole, margin=cfg.margin, sole_thickness=cfg.sole_thickness,
                          clearance=cfg.clearance)
        if f is None:
            under = [s.name for s in terrain.surfaces if s.contains_xy(xy)]
            raise PlanningError(
                f"goal ({goal[0]:.3f}, {goal[1]:.3f}) m is off the terrain: no contact surface holds the {side} "
                f"foot at ({xy[0]:.3f}, {xy[1]:.3f}) with its sole {cfg.margin} m inside and free of the boxes"
                f" (surfaces above that point: {under or 'none'})")
        out[side] = f
    return out


def _is_at(f: Foothold, target: np.ndarray) -> bool:
    return bool(np.linalg.norm(f.footstep.p_world_sole[:2] - target) < 1e-6)


def _search(terrain: ContactTerrain, start: dict[Side, Foothold], targets: dict[Side, np.ndarray], yaw: float,
            sole: SoleRectangle, cfg: ContactPlannerConfig) -> list[Foothold]:
    h, l = _heading_axes(yaw)
    dxs = np.arange(-cfg.max_backward, cfg.max_step_length + 1e-9, cfg.grid)
    ws = np.arange(cfg.min_width, cfg.max_width + 1e-9, cfg.grid)
    DX, W = np.meshgrid(dxs, ws, indexing="ij")
    DX, W = DX.ravel(), W.ravel()
    checks = 0
    visited: set[tuple] = set()
    best_state: tuple[float, list[Foothold], dict[Side, Foothold]] = (np.inf, [], start)

    def key(feet: dict[Side, Foothold], moving: Side) -> tuple:
        return (moving,) + tuple(tuple(np.round(feet[s].footstep.p_world_sole[:2] / 1e-4).astype(int).tolist())
                                 for s in (Side.LEFT, Side.RIGHT))

    def children(feet: dict[Side, Foothold], moving: Side) -> Iterator[Foothold]:
        """Feasible placements of the moving foot, best first (evaluated at once, built lazily)."""
        nonlocal checks
        stance = feet[moving.other].footstep
        ps = stance.p_world_sole[:2]
        cand = ps + np.outer(DX, h) + np.outer(moving.sign * W, l)
        penalty = 1e-3 * np.abs(W - cfg.foot_separation)
        target = targets[moving]
        rel = target - ps
        fwd, lat = rel @ h, moving.sign * (rel @ l)
        if -cfg.max_backward - 1e-9 <= fwd <= cfg.max_step_length + 1e-9 and \
                cfg.min_width - 1e-9 <= lat <= cfg.max_width + 1e-9:
            cand = np.vstack([cand, target])
            penalty = np.append(penalty, 0.0)
        dist = np.linalg.norm(cand - target, axis=1)
        current = float(np.linalg.norm(feet[moving].footstep.p_world_sole[:2] - target))
        keep = (dist < current - cfg.min_progress) | (dist < 1e-9)
        cand, dist, penalty = cand[keep], dist[keep], penalty[keep]
        if len(cand) == 0:
            return
        checks += len(cand)
        k, z, m = _evaluate(terrain, cand, yaw, sole, cfg.margin, cfg.sole_thickness, cfg.clearance)
        ok = (k >= 0) & (np.abs(z - stance.p_world_sole[2]) <= cfg.max_step_height + 1e-9)
        score = dist + penalty - cfg.margin_bonus * np.minimum(m, cfg.margin_cap)
        order = np.flatnonzero(ok)[np.argsort(score[ok], kind="stable")]
        stance_print = sole.footprint(stance.p_world_sole, stance.R_world_sole)
        for i in order:
            f = _make_foothold(terrain, moving, cand[i], int(k[i]), yaw, m[i])
            if polygons_penetration(sole.footprint(f.footstep.p_world_sole, f.footstep.R_world_sole),
                                    stance_print) > 1e-9:
                continue
            yield f

    def remaining(feet: dict[Side, Foothold]) -> float:
        return sum(float(np.linalg.norm(feet[s].footstep.p_world_sole[:2] - targets[s])) for s in feet)

    moving = cfg.first_side
    if _is_at(start[moving], targets[moving]):
        moving = moving.other
    stack: list[tuple[dict[Side, Foothold], Side, list[Foothold], Iterator[Foothold]]] = []
    stack.append((dict(start), moving, [], children(start, moving)))
    visited.add(key(start, moving))
    while stack:
        feet, moving, steps, options = stack[-1]
        f = next(options, None)
        if f is None:
            stack.pop()
            continue
        new_feet = dict(feet)
        new_feet[moving] = f
        new_steps = steps + [f]
        rem = remaining(new_feet)
        if rem < best_state[0]:
            best_state = (rem, new_steps, new_feet)
        if all(_is_at(new_feet[s], targets[s]) for s in new_feet):
            return new_steps
        nxt = moving.other
        if _is_at(new_feet[nxt], targets[nxt]):
            nxt = moving
        k = key(new_feet, nxt)
        if k in visited:
            continue
        visited.add(k)
        if checks > cfg.max_checks:
            break
        stack.append((new_feet, nxt, new_steps, children(new_feet, nxt)))
    _, steps, feet = best_state
    where = ", ".join(f"{s} on {feet[s].surface.name!r} at ({feet[s].footstep.p_world_sole[0]:.3f}, "
                      f"{feet[s].footstep.p_world_sole[1]:.3f}, {feet[s].footstep.p_world_sole[2]:.3f})"
                      for s in (Side.LEFT, Side.RIGHT))
    why = "the candidate budget max_checks ran out" if checks > cfg.max_checks else "every branch dead-ends"
    raise PlanningError(f"no reachable next surface: the search got no further than {len(steps)} step(s) ({where});"
                     f" {why} (max_step_length {cfg.max_step_length} m, max_step_height {cfg.max_step_height} m, "
                     f"margin {cfg.margin} m)")


def _heading(start_feet: Mapping[Side, Footstep]) -> float:
    yaws = [yaw_of(start_feet[s].R_world_sole) for s in (Side.LEFT, Side.RIGHT)]
    return float(np.arctan2(np.mean(np.sin(yaws)), np.mean(np.cos(yaws))))


def _start(terrain: ContactTerrain, start_feet: Mapping[Side, Footstep], sole: SoleRectangle
           ) -> dict[Side, Foothold]:
    feet = {Side.parse(s): f for s, f in dict(start_feet).items()}
    if set(feet) != {Side.LEFT, Side.RIGHT}:
        raise PlanningError("start_feet needs a Footstep for each of left and right")
    out = {}
    for side, f in feet.items():
        if not isinstance(f, Footstep) or f.side is not side:
            raise PlanningError(f"start_feet[{side}] must be a Footstep of side {side}")
        s = locate_foot(terrain, f, sole)
        out[side] = Foothold(f, s, s.footprint_margin(f.p_world_sole, f.R_world_sole, sole))
    return out


def _contact_plan(start: dict[Side, Foothold], steps: list[Foothold], timing: StepTiming, sole: SoleRectangle,
                  cfg: ContactPlannerConfig, terrain: ContactTerrain, method: str) -> ContactPlan:
    plan = FootstepPlan({s: f.footstep for s, f in start.items()}, tuple(f.footstep for f in steps), timing,
                        sole, cfg.reach_limits())
    return ContactPlan(plan, {s: f.surface for s, f in start.items()}, tuple(f.surface for f in steps),
                       tuple(f.margin for f in steps), method, terrain, cfg)


def plan_contacts(terrain: ContactTerrain, start_feet: Mapping[Side, Footstep], goal: Sequence[float], *,
                  timing: StepTiming, sole: SoleRectangle, config: ContactPlannerConfig | None = None) -> ContactPlan:
    """Plan foot placements from the start feet to a goal, by greedy forward placement with backtracking.

    Args:
        terrain: the contact terrain.
        start_feet: Side -> Footstep, the feet at t = 0 (each must stand on a surface, see `locate_foot`).
        goal: (x, y) [m] of the final midpoint between the feet; the feet end side by side at
            +-foot_separation / 2 across the heading (the start feet's yaw, kept throughout).
        timing: the step durations of the resulting FootstepPlan.
        sole: the foot's contact rectangle.
        config: limits and search settings.

    Returns:
        ContactPlan, method "greedy-dfs".

    Raises:
        ValueError: a start foot on no surface; the goal off the terrain; no reachable next surface (gap,
            wall, step too high or too far); the search budget exhausted.
    """
    cfg = config if config is not None else ContactPlannerConfig()
    g = np.asarray(goal, float).ravel()
    if g.shape != (2,) or not np.all(np.isfinite(g)):
        raise PlanningError(f"goal must be 2 finite numbers (x, y) [m], got {goal!r}")
    start = _start(terrain, start_feet, sole)
    yaw = _heading({s: f.footstep for s, f in start.items()})
    s_mid = 0.5 * (start[Side.LEFT].footstep.p_world_sole[:2] + start[Side.RIGHT].footstep.p_world_sole[:2])
    to_goal = g - s_mid
    if np.linalg.norm(to_goal) > cfg.max_step_length:
        bearing = abs(float(np.arctan2(to_goal[1], to_goal[0])) - yaw)
        bearing = min(bearing, 2.0 * np.pi - bearing)
        if bearing > cfg.max_goal_bearing:
            raise PlanningError(f"goal ({g[0]:.3f}, {g[1]:.3f}) is {np.rad2deg(bearing):.0f} deg off the start heading "
                             f"({np.rad2deg(yaw):.0f} deg); this planner keeps the heading and does not turn "
                             f"(max_goal_bearing {np.rad2deg(cfg.max_goal_bearing):.0f} deg): turn first or give "
                             "explicit placements")
    goal_feet = _goal_footholds(terrain, g, yaw, sole, cfg)
    _check_reachable(terrain, yaw, sole, cfg, start, goal_feet)
    targets = {s: f.footstep.p_world_sole[:2].copy() for s, f in goal_feet.items()}
    if all(_is_at(start[s], targets[s]) for s in start):
        steps: list[Foothold] = []
    else:
        steps = _search(terrain, start, targets, yaw, sole, cfg)
    return _contact_plan(start, steps, timing, sole, cfg, terrain, "greedy-dfs")


def contacts_from_placements(terrain: ContactTerrain, start_feet: Mapping[Side, Footstep],
                             placements: Sequence[Footstep | tuple], *, timing: StepTiming, sole: SoleRectangle,
                             config: ContactPlannerConfig | None = None) -> ContactPlan:
    """A contact plan from explicit placements, checked against the terrain and the limits.

    Args:
        placements: in step order, each either a Footstep (checked: on a surface plane within 1 mm, its normal
            the surface's within 1 degree, sole inside by `margin`, sole box free) or a tuple (side, x, y) or
            (side, x, y, yaw) [m, rad] projected on the highest surface that holds it (yaw defaults to the
            start heading).
        Others: as `plan_contacts`.

    Raises:
        ValueError: naming the placement: not on any surface, outside by the margin, colliding, beyond reach.
    """
    cfg = config if config is not None else ContactPlannerConfig()
    start = _start(terrain, start_feet, sole)
    heading = _heading({s: f.footstep for s, f in start.items()})
    feet = dict(start)
    steps = []
    for i, pl in enumerate(placements):
        if isinstance(pl, Footstep):
            side = pl.side
            try:
                s = locate_foot(terrain, pl, sole, tolerance=1e-3, angle_tolerance=np.deg2rad(1.0))
            except ValueError as exc:
                raise PlanningError(f"placement {i}: {exc}") from None
            m = s.footprint_margin(pl.p_world_sole, pl.R_world_sole, sole)
            if m < cfg.margin - 1e-9:
                raise PlanningError(f"placement {i} ({side} foot): the sole is only {m:.4f} m inside {s.name!r}, "
                                 f"less than the margin {cfg.margin} m")
            if not _sole_free(terrain, pl.p_world_sole[None], pl.R_world_sole[None], s.normal, sole,
                              cfg.sole_thickness, cfg.clearance)[0]:
                raise PlanningError(f"placement {i} ({side} foot): the sole box comes closer than {cfg.clearance} m to "
                                 "a terrain box (or penetrates it)")
            f = Foothold(pl, s, m)
        else:
            try:
                side, x, y, *rest = pl
                side = Side.parse(side)
                yaw = float(rest[0]) if rest else heading
            except (TypeError, ValueError):
                raise PlanningError(f"placement {i} must be a Footstep or (side, x, y[, yaw]), got {pl!r}") from None
            f = find_foothold(terrain, side, (float(x), float(y)), yaw, sole, margin=cfg.margin,
                              sole_thickness=cfg.sole_thickness, clearance=cfg.clearance)
            if f is None:
                under = [s.name for s in terrain.surfaces if s.contains_xy(np.array([x, y], float))]
                raise PlanningError(f"placement {i} ({side} foot at ({float(x):.3f}, {float(y):.3f})): no contact "
                                 f"surface holds the sole {cfg.margin} m inside and free of the boxes (surfaces "
                                 f"above that point: {under or 'none'})")
        stance = feet[side.other].footstep
        h, l = _heading_axes(heading)
        d = f.footstep.p_world_sole - stance.p_world_sole
        if abs(d[:2] @ h) > cfg.max_step_length + 1e-9:
            raise PlanningError(f"placement {i} ({side} foot): {d[:2] @ h:+.3f} m forward of the stance foot, beyond "
                             f"max_step_length {cfg.max_step_length} m")
        if abs(d[2]) > cfg.max_step_height + 1e-9:
            raise PlanningError(f"placement {i} ({side} foot): {d[2]:+.3f} m above the stance foot, beyond "
                             f"max_step_height {cfg.max_step_height} m")
        feet[side] = f
        steps.append(f)
    return _contact_plan(start, steps, timing, sole, cfg, terrain, "explicit")
