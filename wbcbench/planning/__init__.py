"""Walking planning, robot-model free: footstep plans, swing trajectories, ZMP preview-control pattern generator.

Everything takes numbers (foot poses, sole size, CoM height, gravity, dt) and returns time-indexed trajectory
objects with per-tick arrays and `at(t)`; frames are in the names (`p_world_com`, `T_world_sole`).

    plan = straight_walk(6, 0.20, foot_separation=0.1714, sole=SoleRectangle(0.20, 0.13),
                         timing=StepTiming(single_support=0.9, double_support=0.115))
    walk = generate_walk(plan, PatternGeneratorConfig(com_height=0.87))
    ref = walk.at(4.2)          # WalkSample: CoM, ZMP, DCM, feet, contacts at t = 4.2 s
"""

from .footsteps import (
    Footstep,
    FootstepPlan,
    ReachLimits,
    StepIncrement,
    StepTiming,
    footsteps_from_increments,
    lateral_walk,
    straight_walk,
    turning_walk,
)
from .geometry import SoleRectangle, convex_hull, polygon_margin, polygons_penetration, support_polygon
from .pattern_generator import PatternGeneratorConfig, ZmpTransfer, generate_walk, zmp_reference
from .preview_control import PreviewControlError, PreviewGains, cart_table, preview_gains, simulate_preview
from ..side import Side
from .swing import SwingSample, SwingTrajectory, quintic_blend
from .terrain import (
    ContactSurface,
    ContactTerrain,
    OrientedBox,
    boxes_to_yaml,
    platform_boxes,
    rpy_matrix,
    stairs_boxes,
)
from .contact_planner import (
    ContactPlan,
    ContactPlannerConfig,
    Foothold,
    contacts_from_placements,
    find_foothold,
    locate_foot,
    plan_contacts,
)
from .centroidal import (
    CentroidalConfig,
    LegReach,
    CentroidalPlanError,
    CentroidalReport,
    CentroidalTrajectory,
    ContactWrenchTrajectory,
    plan_centroidal,
)
from .multicontact import MultiContactWalk, generate_multicontact_walk, plan_swing, swing_penetration, terrain_walk
from .trajectory import (
    ContactEvent,
    ContactEventKind,
    ContactSchedule,
    FootSample,
    FootTrajectory,
    WalkSample,
    WalkTrajectory,
)

__all__ = [
    # feet and footsteps
    "Side",
    "SoleRectangle",
    "Footstep",
    "StepTiming",
    "ReachLimits",
    "FootstepPlan",
    "StepIncrement",
    "footsteps_from_increments",
    "straight_walk",
    "lateral_walk",
    "turning_walk",
    # swing
    "SwingTrajectory",
    "SwingSample",
    "quintic_blend",
    # preview control and pattern generator
    "PreviewGains",
    "PreviewControlError",
    "cart_table",
    "preview_gains",
    "simulate_preview",
    "ZmpTransfer",
    "PatternGeneratorConfig",
    "zmp_reference",
    "generate_walk",
    # trajectories
    "WalkTrajectory",
    "WalkSample",
    "FootTrajectory",
    "FootSample",
    "ContactSchedule",
    "ContactEvent",
    "ContactEventKind",
    # uneven terrain
    "OrientedBox",
    "ContactSurface",
    "ContactTerrain",
    "rpy_matrix",
    "stairs_boxes",
    "platform_boxes",
    "boxes_to_yaml",
    "ContactPlannerConfig",
    "Foothold",
    "ContactPlan",
    "find_foothold",
    "locate_foot",
    "plan_contacts",
    "contacts_from_placements",
    "CentroidalConfig",
    "LegReach",
    "CentroidalPlanError",
    "CentroidalReport",
    "ContactWrenchTrajectory",
    "CentroidalTrajectory",
    "plan_centroidal",
    "MultiContactWalk",
    "plan_swing",
    "swing_penetration",
    "generate_multicontact_walk",
    "terrain_walk",
    # geometry
    "convex_hull",
    "polygon_margin",
    "polygons_penetration",
    "support_polygon",
]
