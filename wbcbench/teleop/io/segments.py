"""Segment names shared by the readers, the UDP stream and the retargeting.

Canonical names are the 23 segments of the Xsens MVN body model (the suit used in paper 004), numbered 1..23 in
MVN order; these numbers are the segment ids of the UDP pose stream (:mod:`wbcbench.teleop.link.protocol`). Readers
keep the names found in the file; :func:`canonical_name` maps common aliases (BVH exports from other tools) to
the canonical ones when the retargeting looks segments up.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

__all__ = [
    "MVN_SEGMENTS",
    "MVN_SEGMENT_IDS",
    "MVN_PARENTS",
    "KEYPOINTS",
    "SEGMENT_ALIASES",
    "canonical_name",
]

#: The 23 Xsens MVN segments in MVN order; the UDP segment id of ``MVN_SEGMENTS[i]`` is ``i + 1``.
MVN_SEGMENTS: tuple[str, ...] = (
    "Pelvis", "L5", "L3", "T12", "T8", "Neck", "Head",
    "RightShoulder", "RightUpperArm", "RightForeArm", "RightHand",
    "LeftShoulder", "LeftUpperArm", "LeftForeArm", "LeftHand",
    "RightUpperLeg", "RightLowerLeg", "RightFoot", "RightToe",
    "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "LeftToe",
)  # fmt: skip

#: Segment name -> UDP segment id (1..23).
MVN_SEGMENT_IDS: Mapping[str, int] = MappingProxyType({name: i + 1 for i, name in enumerate(MVN_SEGMENTS)})

#: Parent of each MVN segment (``None`` for the pelvis).
MVN_PARENTS: Mapping[str, str | None] = MappingProxyType({
    "Pelvis": None, "L5": "Pelvis", "L3": "L5", "T12": "L3", "T8": "T12", "Neck": "T8", "Head": "Neck",
    "RightShoulder": "T8", "RightUpperArm": "RightShoulder", "RightForeArm": "RightUpperArm",
    "RightHand": "RightForeArm",
    "LeftShoulder": "T8", "LeftUpperArm": "LeftShoulder", "LeftForeArm": "LeftUpperArm", "LeftHand": "LeftForeArm",
    "RightUpperLeg": "Pelvis", "RightLowerLeg": "RightUpperLeg", "RightFoot": "RightLowerLeg",
    "RightToe": "RightFoot",
    "LeftUpperLeg": "Pelvis", "LeftLowerLeg": "LeftUpperLeg", "LeftFoot": "LeftLowerLeg", "LeftToe": "LeftFoot",
})  # fmt: skip

#: The segment origins used as the point cloud of the Umeyama alignment and the model fit: pelvis, mid-thorax,
#: head (upper neck joint), shoulders, elbows, wrists, hips, knees and ankles.
KEYPOINTS: tuple[str, ...] = (
    "Pelvis", "T8", "Head",
    "LeftUpperArm", "LeftForeArm", "LeftHand", "RightUpperArm", "RightForeArm", "RightHand",
    "LeftUpperLeg", "LeftLowerLeg", "LeftFoot", "RightUpperLeg", "RightLowerLeg", "RightFoot",
)  # fmt: skip

#: Aliases (lower case) of canonical names, from common BVH skeletons (CMU, Mixamo without its prefix,
#: Rokoko, Axis Neuron). A name already canonical maps to itself.
SEGMENT_ALIASES: Mapping[str, str] = MappingProxyType({
    "hips": "Pelvis", "pelvis": "Pelvis", "root": "Pelvis",
    "spine2": "T8", "chest": "T8", "upperchest": "T8", "spine3": "T8", "thorax": "T8",
    "head": "Head", "neck": "Neck",
    "leftarm": "LeftUpperArm", "leftupperarm": "LeftUpperArm", "lshoulder": "LeftUpperArm",
    "leftforearm": "LeftForeArm", "leftlowerarm": "LeftForeArm", "lelbow": "LeftForeArm",
    "lefthand": "LeftHand", "lwrist": "LeftHand",
    "rightarm": "RightUpperArm", "rightupperarm": "RightUpperArm", "rshoulder": "RightUpperArm",
    "rightforearm": "RightForeArm", "rightlowerarm": "RightForeArm", "relbow": "RightForeArm",
    "righthand": "RightHand", "rwrist": "RightHand",
    "leftupleg": "LeftUpperLeg", "leftupperleg": "LeftUpperLeg", "leftthigh": "LeftUpperLeg",
    "leftleg": "LeftLowerLeg", "leftlowerleg": "LeftLowerLeg", "leftshin": "LeftLowerLeg",
    "leftfoot": "LeftFoot", "leftankle": "LeftFoot",
    "rightupleg": "RightUpperLeg", "rightupperleg": "RightUpperLeg", "rightthigh": "RightUpperLeg",
    "rightleg": "RightLowerLeg", "rightlowerleg": "RightLowerLeg", "rightshin": "RightLowerLeg",
    "rightfoot": "RightFoot", "rightankle": "RightFoot",
})  # fmt: skip

_CANONICAL_LOWER = {name.lower(): name for name in MVN_SEGMENTS}


def canonical_name(name: str) -> str | None:
    """The canonical MVN name of a segment called ``name`` in a file, or ``None`` if unknown.

    Exact MVN names win; then the alias table (case-insensitive, a ``prefix:`` such as Mixamo's
    ``mixamorig:`` is ignored).
    """
    if name in MVN_SEGMENT_IDS:
        return name
    key = name.rsplit(":", 1)[-1].strip().lower()
    return _CANONICAL_LOWER.get(key) or SEGMENT_ALIASES.get(key)
