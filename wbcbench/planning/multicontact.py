"""Walking on uneven terrain: contact plan -> swing feet clearing the terrain -> centroidal QP -> WalkTrajectory.

The multi-contact counterpart of `generate_walk` (paper 000, Section 5.2, where the loco-3d planner plays this
role for the tilted platforms and the stairs): the result is the same `WalkTrajectory` container, so the
controllers and the walk scenario use it unchanged, plus the centroidal plan (contact wrenches, angular
momentum) for those who want it.

    terrain = ContactTerrain.from_boxes(stairs_boxes())
    contacts = plan_contacts(terrain, start_feet, goal=(1.95, 0.0), timing=timing, sole=sole)
    mc = generate_multicontact_walk(contacts, CentroidalConfig(mass=90.27, com_height=0.87))
    ref = mc.walk.at(4.2)

Swing feet (`plan_swing`): a `SwingTrajectory` between the two footholds with its apex `swing_clearance`
(default 5 cm) above the highest terrain under the swept footprints (the convex hull of the start and end
footprints: the top faces of the boxes clipped to it, their highest point), counted for the lowest corner of
the tilted sole, and never lower than `swing_clearance` above the higher foothold. The sole box (the sole
rectangle extruded by `sole_thickness` along the sole normal, as the simulator's sole geom) is then checked
against every terrain box and the floor at every tick of the swing, grown by `edge_margin` (2 cm) in the sole
plane so that edges are passed at least that far. If it penetrates anywhere, milder to stronger changes are
tried until one is clean: the apex raised by steps of 2 cm (up to 10 cm more) and the horizontal motion
confined to a window (w0, w1) of the swing (lift first, move, then descend; w0 in 0, 0.1, 0.2, 0.3 and w1 in
1, 0.9, 0.8, 0.7), 2 cm of apex counting as much as 1/15 of the swing cut from the window; a ValueError names
the step if none is clean.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import PlanningError
from .centroidal import CentroidalConfig, CentroidalTrajectory, plan_centroidal
from .contact_planner import ContactPlan, ContactPlannerConfig, plan_contacts
from .footsteps import Footstep, FootstepPlan, StepTiming
from .geometry import SoleRectangle, convex_hull
from .swing import SwingTrajectory, foot_arrays, write_swing
from .terrain import ContactTerrain, sole_box
from .trajectory import ContactEvent, ContactEventKind, ContactSchedule, FootTrajectory, WalkTrajectory
from ..side import Side

__all__ = ["MultiContactWalk", "plan_swing", "swing_penetration", "generate_multicontact_walk", "terrain_walk"]

_WINDOWS = tuple((w0, w1) for w0 in (0.0, 0.1, 0.2, 0.3) for w1 in (1.0, 0.9, 0.8, 0.7))
_APEX_RAISES = (0.0, 0.02, 0.04, 0.06, 0.08, 0.10)
# tried mildest first: 2 cm more apex count as much as a horizontal window 1/15 of the swing shorter
_SHAPES = sorted(((r, w) for r in _APEX_RAISES for w in _WINDOWS),
                 key=lambda rw: rw[0] / 0.02 + 15.0 * (rw[1][0] + 1.0 - rw[1][1]))


def _clip(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """Sutherland-Hodgman: the part of convex polygon `subject` inside convex counter-clockwise `clip`, (k, 2)."""
    out = np.asarray(subject, float)
    for a, b in zip(clip, np.roll(clip, -1, axis=0)):
        if len(out) == 0:
            break
        e = b - a
        side = e[0] * (out[:, 1] - a[1]) - e[1] * (out[:, 0] - a[0])  # >= 0 inside (left of the edge)
        new = []
        for i in range(len(out)):
            p, q = out[i], out[(i + 1) % len(out)]
            sp_, sq = side[i], side[(i + 1) % len(out)]
            if sp_ >= 0.0:
                new.append(p)
            if (sp_ >= 0.0) != (sq >= 0.0):
                new.append(p + (q - p) * (sp_ / (sp_ - sq)))
        out = np.array(new).reshape(-1, 2)
    return out


def _terrain_height_under(terrain: ContactTerrain, region: np.ndarray) -> float:
    """Highest point of the terrain above the convex x-y region (k, 2) [m]: top faces clipped to the region,
    and the vertices of boxes without a walkable top that project into it."""
    top = 0.0 if terrain.floor else -np.inf
    covered = set()
    for s in terrain.surfaces:
        if s.box_index is not None:
            covered.add(s.box_index)
        if s.name == "floor":
            continue
        part = _clip(s.vertices[:, :2], region)
        if len(part):
            top = max(top, float(np.max(s.height_at(part))))
    for i, box in enumerate(terrain.boxes):
        if i in covered:
            continue
        v = box.vertices()
        inside = _clip(convex_hull(v[:, :2]), region)  # any overlap: take the box's highest vertex (conservative)
        if len(inside):
            top = max(top, float(v[:, 2].max()))
    return top


def _corner_drop(foot: Footstep, sole: SoleRectangle) -> float:
    """How far the lowest sole corner lies below the sole origin [m] (tilted soles)."""
    z = (sole.corners_in_sole() @ foot.R_world_sole.T)[:, 2]
    return max(0.0, -float(z.min()))


def swing_penetration(swing: SwingTrajectory, terrain: ContactTerrain, sole: SoleRectangle, times: np.ndarray,
                      sole_thickness: float = 0.02, edge_margin: float = 0.0) -> np.ndarray:
    """Penetration depth of the swinging sole box into the terrain at each time (n,) [m] (> 0: collision).

    With `edge_margin` > 0 the box is grown by that much in the sole plane (length and width) first.
    """
    sample = swing.sample(np.asarray(times, float))
    center, half = sole_box(sample.p_world_sole, sample.R_world_sole, sole, sole_thickness)
    return terrain.penetration(center, sample.R_world_sole, half + np.array([edge_margin, edge_margin, 0.0]))


def plan_swing(start: Footstep, end: Footstep, t_start: float, duration: float, terrain: ContactTerrain,
               sole: SoleRectangle, *, swing_clearance: float = 0.05, sole_thickness: float = 0.02,
               edge_margin: float = 0.02, apex_phase: float = 0.5, dt: float = 1e-3,
               step: int | None = None) -> SwingTrajectory:
    """A swing from `start` to `end` that clears the terrain (see the module docstring).

    Args:
        start, end: the footholds (same foot).
        t_start, duration: lift-off time and swing duration [s].
        terrain: the terrain to clear.
        sole: the foot's contact rectangle.
        swing_clearance: apex above the highest terrain under the swept footprints [m].
        sole_thickness: height of the checked sole box [m].
        edge_margin: the checked sole box is grown by this much in the sole plane [m], so that the swinging
            foot passes stair edges and platform borders at least that far (horizontally); it must not exceed
            the footholds' own clearance from the boxes (the contact planner's `clearance`, 0.02), since the
            grown box is also checked at lift-off and touch-down.
        apex_phase: fraction of the swing at the apex.
        dt: sampling period of the penetration check [s].
        step: step index, for the error message.

    Raises:
        ValueError: no swing of the tried shapes clears the terrain.
    """
    if not np.isfinite(swing_clearance) or swing_clearance < 0.0:
        raise PlanningError(f"swing_clearance must be >= 0 [m], got {swing_clearance!r}")
    prints = np.vstack([sole.footprint(f.p_world_sole, f.R_world_sole) for f in (start, end)])
    region = convex_hull(prints)
    z_terrain = _terrain_height_under(terrain, region) + max(_corner_drop(start, sole), _corner_drop(end, sole))
    z_high = max(start.p_world_sole[2], end.p_world_sole[2])
    base_apex = max(0.0, z_terrain - z_high) + swing_clearance
    n = max(2, int(round(duration / dt)) + 1)
    times = t_start + np.linspace(0.0, duration, n)
    worst = (np.inf, None)
    for raise_, window in _SHAPES:
        sw = SwingTrajectory.between(start, end, t_start, duration, apex_height=base_apex + raise_,
                                     apex_phase=apex_phase, horizontal_window=window)
        depth = swing_penetration(sw, terrain, sole, times, sole_thickness, edge_margin)
        if depth.max() <= 1e-6:
            return sw
        if depth.max() < worst[0]:
            worst = (float(depth.max()), float(times[int(np.argmax(depth))]))
    what = f"step {step} ({start.side} foot)" if step is not None else f"the {start.side} swing"
    raise PlanningError(f"{what}: no swing clears the terrain: the sole box (grown by edge_margin {edge_margin} m) "
                     f"still penetrates it by at least {worst[0]:.4f} m (at t = {worst[1]:.3f} s), with the apex "
                     f"raised by up to {_APEX_RAISES[-1]} m and the horizontal motion confined to as little as "
                     f"{_WINDOWS[-1]} of the swing")


@dataclass(frozen=True, eq=False)
class MultiContactWalk:
    """A walk on uneven terrain.

    Attributes:
        walk: the per-tick references (CoM, ZMP, DCM, feet, contacts), as `generate_walk` returns them:
            p_world_zmp_ref is the ZMP of the planned contact wrenches on the horizontal plane at the support
            height, p_world_zmp the ZMP the CoM motion implies with L_dot = 0 (they differ by the planned
            L_dot), com_height the nominal height and omega = sqrt(g / com_height).
        centroidal: the centroidal plan (contact wrenches per foot, angular momentum, solver report).
        contacts: the contact plan (surfaces of the footholds), or None if built from a bare FootstepPlan.
        swings: the swing of each step.
        max_swing_penetration: largest penetration of a swinging sole box (not grown) into the terrain [m]
            (<= 1e-6; touching at lift-off and touch-down gives about 0).
    """

    walk: WalkTrajectory
    centroidal: CentroidalTrajectory
    contacts: ContactPlan | None
    swings: tuple[SwingTrajectory, ...]
    max_swing_penetration: float


def _feet(plan: FootstepPlan, swings: Sequence[SwingTrajectory], in_contact: Mapping[Side, np.ndarray],
          dt: float) -> tuple[dict[Side, FootTrajectory], ContactSchedule]:
    n = len(in_contact[Side.LEFT])
    t = np.arange(n) * dt
    arrays = {}
    for side in Side:
        foot = plan.initial_feet[side]
        arrays[side] = foot_arrays(foot.p_world_sole, foot.R_world_sole, n)
    events = []
    for i, (step, sw) in enumerate(zip(plan.steps, swings)):
        lo, td = int(round(sw.t_start / dt)), int(round(sw.t_end / dt))
        write_swing(arrays[step.side], sw.sample(t[lo:td]), lo, td, step.p_world_sole, step.R_world_sole)
        events.append(ContactEvent(ContactEventKind.LIFT_OFF, step.side, lo, lo * dt, i))
        events.append(ContactEvent(ContactEventKind.TOUCH_DOWN, step.side, td, td * dt, i))
    feet = {s: FootTrajectory(s, a["p"], a["R"], a["v"], a["w"], a["a"], a["dw"], in_contact[s])
            for s, a in arrays.items()}
    schedule = ContactSchedule(dt, dict(in_contact), tuple(sorted(events, key=lambda e: (e.tick, e.kind.value))))
    return feet, schedule


def generate_multicontact_walk(contacts: ContactPlan | FootstepPlan, config: CentroidalConfig, *,
                               terrain: ContactTerrain | None = None, swing_clearance: float = 0.05,
                               sole_thickness: float | None = None, edge_margin: float = 0.02,
                               apex_phase: float = 0.5, p_world_com_init: np.ndarray | None = None
                               ) -> MultiContactWalk:
    """Centroidal plan, terrain-clearing swings and per-tick walking references for a contact plan.

    Args:
        contacts: a ContactPlan (from `plan_contacts` or `contacts_from_placements`), or a bare FootstepPlan
            together with `terrain`.
        config: the centroidal QP settings (mass, nominal CoM height, friction, weights, dt).
        terrain: the terrain for the swing check; default: the contact plan's.
        swing_clearance: apex above the terrain under each swing [m].
        sole_thickness: height of the sole box checked [m]; default: the contact planner's (0.02).
        edge_margin: horizontal margin of the swing check [m] (see `plan_swing`).
        apex_phase: fraction of the swing at the apex.
        p_world_com_init: the CoM at t = 0 (3,) [m]; default over the initial feet at the nominal height.

    Raises:
        ValueError: a swing that cannot clear the terrain, bad inputs.
        CentroidalPlanError: the centroidal QP failed.
    """
    if isinstance(contacts, ContactPlan):
        plan = contacts.footsteps
        terrain = terrain if terrain is not None else contacts.terrain
        thickness = sole_thickness if sole_thickness is not None else contacts.config.sole_thickness
        contact_plan: ContactPlan | None = contacts
    elif isinstance(contacts, FootstepPlan):
        if terrain is None:
            raise PlanningError("a bare FootstepPlan needs the terrain (terrain=...) for the swing check")
        plan, contact_plan = contacts, None
        thickness = sole_thickness if sole_thickness is not None else 0.02
    else:
        raise PlanningError(f"contacts must be a ContactPlan or a FootstepPlan, got {type(contacts).__name__}")
    dt = config.dt
    swings = []
    feet = dict(plan.initial_feet)
    worst = -np.inf
    for i, step in enumerate(plan.steps):
        lo, td = int(round(plan.lift_off_time(i) / dt)), int(round(plan.touch_down_time(i) / dt))
        sw = plan_swing(feet[step.side], step, lo * dt, (td - lo) * dt, terrain, plan.sole,
                        swing_clearance=swing_clearance, sole_thickness=thickness, edge_margin=edge_margin,
                        apex_phase=apex_phase, dt=dt, step=i)
        worst = max(worst, float(swing_penetration(sw, terrain, plan.sole, np.arange(lo, td + 1) * dt,
                                                   thickness).max()))
        swings.append(sw)
        feet[step.side] = step
    # the swings first: the centroidal plan bounds the swinging legs' reach at their planned poses (LegReach)
    centroidal = plan_centroidal(plan, config, p_world_com_init, swings)
    in_contact = {s: centroidal.wrenches[s].in_contact for s in Side}
    foot_traj, schedule = _feet(plan, swings, in_contact, dt)
    walk = WalkTrajectory(dt, config.com_height, config.gravity, config.omega, centroidal.p_world_com,
                          centroidal.v_world_com, centroidal.a_world_com, centroidal.p_world_zmp,
                          centroidal.p_world_zmp_com, centroidal.p_world_dcm, foot_traj, schedule, plan.sole, plan)
    return MultiContactWalk(walk, centroidal, contact_plan, tuple(swings), worst)


def terrain_walk(boxes: Sequence[object], start_feet: Mapping[Side, Footstep], goal: Sequence[float], *,
                 timing: StepTiming, sole: SoleRectangle, mass: float, com_height: float = 0.87,
                 floor: bool = True, planner: ContactPlannerConfig | None = None,
                 centroidal: CentroidalConfig | None = None, swing_clearance: float = 0.05,
                 p_world_com_init: np.ndarray | None = None) -> MultiContactWalk:
    """All in one: scene boxes -> contact terrain -> contact plan to `goal` -> multi-contact walk.

    Args:
        boxes: the scene's boxes (`wbcbench.scene.Box`, e.g. `stairs_boxes()` or `platform_boxes()`).
        start_feet: Side -> Footstep at t = 0. goal: (x, y) [m] of the final feet midpoint.
        timing, sole: step durations and the foot rectangle.
        mass: robot mass [kg]. com_height: nominal CoM height above the support [m] (both ignored when
            `centroidal` is given).
        floor: the scene has the floor plane z = 0.
        planner, centroidal: settings (centroidal defaults to CentroidalConfig(mass, com_height)).
        swing_clearance: apex above the terrain under each swing [m].
        p_world_com_init: the CoM at t = 0 [m].
    """
    terrain = ContactTerrain.from_boxes(boxes, floor=floor)
    contact_plan = plan_contacts(terrain, start_feet, goal, timing=timing, sole=sole, config=planner)
    cfg = centroidal if centroidal is not None else CentroidalConfig(mass=mass, com_height=com_height)
    return generate_multicontact_walk(contact_plan, cfg, swing_clearance=swing_clearance,
                                      p_world_com_init=p_world_com_init)
