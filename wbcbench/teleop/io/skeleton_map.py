"""Which segment of a recording's skeleton is which: names first, then the skeleton's topology.

Motion-capture skeletons name the same bones differently (CMU and Mixamo `LeftArm`, Xsens's BVH export
`LeftShoulder` for the upper arm and `LeftCollar` for the clavicle, Bandai-Namco `UpperArm_L`, Rokoko `LeftThigh`,
Axis Neuron `LeftUpLeg`...). Names alone are ambiguous (`LeftShoulder` is the clavicle in the MVN model and in
Mixamo, the upper arm in an Xsens BVH export); the chain they sit in is not. So:

1. `canonical_name` on every segment (exact MVN names and the alias table); if that finds every segment the
   retargeting needs, it is the mapping ("names").
   The names are kept only if the hierarchy agrees (each hand's forearm and upper arm, each foot's lower and upper
   leg, are its nearest ancestors, helper bones skipped).
2. Otherwise ("topology"): on each side, the hand is the shallowest segment whose name says hand or wrist, the
   foot likewise (foot, ankle). The side is read as a prefix or a suffix in any case: `Left`/`Right`, `L_`,
   `l_`, `_L`, `.L` (Blender), `L ` (3ds Max Biped), `lwrist` (CMU ASF); a namespace (`mixamorig:`), a
   `Bip01 ` and a Rigify `DEF-`/`ORG-` prefix are dropped. Walking up the parents from the hand gives the forearm
   and the upper arm (twist/roll helper bones skipped), from the foot the lower and the upper leg; the pelvis is
   the nearest common ancestor of the two upper legs (the root if none); the thorax (T8) is the deepest segment
   carrying both arms; the head is the shallowest segment named head, else (e.g. Rigify's `spine.006`) the end of
   the thorax's other chain: from the thorax down its longest non-arm branch while a segment has one child.

`map_segments` returns the mapping and how it was found; a `segment_map` file (YAML, canonical name -> the
file's segment name) overrides both (`--segment-map`).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ...errors import ConfigError
from .segments import KEYPOINTS, MVN_SEGMENT_IDS, canonical_name

__all__ = ["REQUIRED", "SegmentMapping", "load_segment_map", "map_segments"]

#: The canonical segments the retargeting needs (its keypoints; the hands and head are the effectors).
REQUIRED: tuple[str, ...] = KEYPOINTS

_HELPER = re.compile(r"(twist|roll|share|end$|_end$|nub$)")


@dataclass(frozen=True)
class SegmentMapping:
    """canonical MVN name -> the recording's segment name; `method`: "names", "topology" or "file"."""

    names: dict
    method: str


_PREFIX = re.compile(r"^(bip0*1[ _]|(def|org|mch)[-_.])")
#: words that follow a bare side letter (CMU ASF: lhumerus, rwrist, lfemur ...)
_BARE_SIDE = re.compile(r"^([lr])(humerus|radius|wrist|hand|femur|tibia|foot|toes?|clavicle|collar|shoulder|elbow|"
                        r"hip|knee|ankle|thigh|shin|arm|forearm|upleg|leg|upperarm|lowerarm|upperleg|lowerleg)$")


def _side_and_base(name: str) -> tuple[str | None, str]:
    """('L' | 'R' | None, the name without namespace, side marker and separators, lower case)."""
    n = name.rsplit(":", 1)[-1].strip()
    m = re.match(r"^(.*[a-z])([LR])$", n)  # camel-case suffix: HandL, UpperArmR
    low = _PREFIX.sub("", n.lower())
    for prefix, side in (("left", "L"), ("right", "R")):
        if low.startswith(prefix):
            return side, re.sub(r"[_\-. ]", "", low[len(prefix):])
        if low.endswith(prefix) and len(low) > len(prefix):  # hand_left, HandLeft
            return side, re.sub(r"[_\-. ]", "", low[:-len(prefix)])
    m2 = re.match(r"^([lr])[_\-. ](.+)$", low)
    if m2:
        return m2.group(1).upper(), re.sub(r"[_\-. ]", "", m2.group(2))
    m2 = re.match(r"^(.+?)[_\-. ]([lr])$", low)
    if m2:
        return m2.group(2).upper(), re.sub(r"[_\-. ]", "", m2.group(1))
    m2 = _BARE_SIDE.match(re.sub(r"[_\-. ]", "", low))
    if m2:
        return m2.group(1).upper(), m2.group(2)
    if m:
        return m.group(2), re.sub(r"[_\-. ]", "", m.group(1).lower())
    return None, re.sub(r"[_\-. ]", "", low)


def _depths(parents: Sequence[int]) -> list[int]:
    depth = []
    for i in range(len(parents)):
        d, j = 0, parents[i]
        while j >= 0 and d <= len(parents):
            d, j = d + 1, parents[j]
        depth.append(d)
    return depth


def _walk_up(i: int, parents: Sequence[int], segments: Sequence[str], n: int) -> list[int]:
    """The n proper ancestors of segment i, nearest first, helper bones (twist, roll...) skipped."""
    out, j = [], parents[i]
    while j >= 0 and len(out) < n:
        if not _HELPER.search(segments[j].lower()):
            out.append(j)
        j = parents[j]
    return out


def _common_ancestor(a: int, b: int, parents: Sequence[int], segments: Sequence[str]) -> int | None:
    """The nearest proper common ancestor of segments a and b (helper bones skipped), or None."""
    up_a = _walk_up(a, parents, segments, len(segments))
    up_b = set(_walk_up(b, parents, segments, len(segments)))
    return next((i for i in up_a if i in up_b), None)


def _top_of_spine(thorax: int, arms: set, parents: Sequence[int], segments: Sequence[str]) -> int | None:
    """The head by the hierarchy: from the thorax, into the child (not towards an arm) with the longest branch,
    then down while the segment has exactly one child (helper bones and end sites not counted)."""
    children: dict[int, list[int]] = {}
    for i, p in enumerate(parents):
        if p >= 0 and not _HELPER.search(segments[i].lower()):
            children.setdefault(p, []).append(i)

    def height(i: int) -> int:
        return 1 + max((height(c) for c in children.get(i, [])), default=0)

    def reaches(i: int, targets: set) -> bool:
        return i in targets or any(reaches(c, targets) for c in children.get(i, []))

    spine = [c for c in children.get(thorax, []) if not reaches(c, arms)]
    if not spine:
        return None
    node = max(spine, key=height)
    while len(children.get(node, [])) == 1:
        node = children[node][0]
    return node


def _chains_agree(names: dict, segments: Sequence[str], parents: Sequence[int]) -> bool:
    """Whether a mapping by names fits the hierarchy: hand -> forearm -> upper arm and foot -> lower leg -> upper
    leg are nearest ancestors (helper bones skipped). True when the file gives no hierarchy."""
    if not parents or len(parents) != len(segments) or all(p < 0 for p in parents):
        return True
    index = {s: i for i, s in enumerate(segments)}
    for side in ("Left", "Right"):
        for chain in (("Hand", "ForeArm", "UpperArm"), ("Foot", "LowerLeg", "UpperLeg")):
            ids = [index[names[side + c]] for c in chain]
            if _walk_up(ids[0], parents, segments, 2) != ids[1:]:
                return False
    return True


def map_segments(segments: Sequence[str], parents: Sequence[int], source: str = "") -> SegmentMapping:
    """The segments the retargeting needs (:data:`REQUIRED`) in a skeleton (module docstring).

    Raises:
        ConfigError: neither the names nor the topology give every required segment (the message lists what is
            missing and names `--segment-map`).
    """
    by_name: dict[str, str] = {}
    for s in segments:
        c = canonical_name(s)
        if c is not None and c not in by_name:
            by_name[c] = s
    if all(r in by_name for r in REQUIRED) and _chains_agree(by_name, segments, parents):
        return SegmentMapping(by_name, "names")
    if not parents or len(parents) != len(segments) or all(p < 0 for p in parents):
        missing = [r for r in REQUIRED if r not in by_name]
        raise ConfigError(f"skeleton: segments {missing} not found by name and the file gives no hierarchy; "
                          "give --segment-map FILE.yaml (canonical name: segment name)", file=source or None)
    depth = _depths(parents)
    info = [_side_and_base(s) for s in segments]
    out: dict[str, str] = {}

    def shallowest(side: str | None, words: tuple[str, ...]) -> int | None:
        hits = [i for i, (sd, base) in enumerate(info)
                if sd == side and any(base == w or base.startswith(w) for w in words)
                and not _HELPER.search(segments[i].lower())]
        return min(hits, key=lambda i: depth[i]) if hits else None

    roots = [i for i, p in enumerate(parents) if p < 0]
    pelvis = min(roots, key=lambda i: -sum(1 for p in parents if p == i)) if roots else None
    arms, legs = {}, {}
    limbs = ((("hand", "wrist"), ("Hand", "ForeArm", "UpperArm")), (("foot", "ankle"), ("Foot", "LowerLeg", "UpperLeg")))
    for side, prefix in (("L", "Left"), ("R", "Right")):
        for words, names in limbs:  # the extremity by name, the two segments above it by the chain
            end = shallowest(side, words)
            chain = _walk_up(end, parents, segments, 2) if end is not None else []
            if len(chain) == 2:
                for k, name in zip((end, *chain), names):
                    out[prefix + name] = segments[k]
                (arms if names[0] == "Hand" else legs)[side] = chain[1]
    if len(legs) == 2:  # the pelvis: the nearest common ancestor of the upper legs (a root may sit at the floor)
        common = _common_ancestor(legs["L"], legs["R"], parents, segments)
        if common is not None:
            pelvis = common
    if pelvis is not None:
        out["Pelvis"] = segments[pelvis]
    if len(arms) == 2:  # the thorax: the deepest common ancestor of the two upper arms, below any clavicle
        left = [arms["L"], *_walk_up(arms["L"], parents, segments, len(segments))]
        right = set([arms["R"], *_walk_up(arms["R"], parents, segments, len(segments))])
        common = [i for i in left if i in right]
        if common:
            out["T8"] = segments[common[0]]
    head = shallowest(None, ("head",))
    if head is None and "T8" in out and len(arms) == 2:
        head = _top_of_spine(segments.index(out["T8"]), set(arms.values()), parents, segments)
    if head is not None:
        out["Head"] = segments[head]
    for k, v in by_name.items():  # names the topology did not decide (e.g. Neck, the clavicles)
        if k not in out and v not in out.values():
            out[k] = v
    missing = [r for r in REQUIRED if r not in out]
    if missing:
        limbs = [f"{side.lower()} {limb}" for side in ("Left", "Right") for limb, segs in
                 (("arm", ("UpperArm", "ForeArm", "Hand")), ("leg", ("UpperLeg", "LowerLeg", "Foot")))
                 if all(side + s in missing for s in segs)]
        raise ConfigError(f"skeleton: {'no ' + ' and no '.join(limbs) + ': ' if limbs else ''}"
                          f"segments {missing} found neither by name nor by the hierarchy (hands and "
                          "feet must be named hand/wrist and foot/ankle with a side); give --segment-map FILE.yaml "
                          "(canonical name: segment name)", file=source or None)
    return SegmentMapping(out, "topology")


def load_segment_map(path: str | Path, segments: Sequence[str] | None = None) -> SegmentMapping:
    """A YAML file `canonical name: segment name` (e.g. `LeftHand: Hand_L`); checked against the canonical
    names and, when given, the recording's segments.

    Raises:
        ConfigError: unreadable file, an unknown canonical name, a segment the recording does not have, or a
            required segment missing (one line naming the file and the key).
    """
    from ...config import load_yaml

    path = Path(path)
    if not path.is_file():
        raise ConfigError("no such segment map file", file=str(path))
    data = load_yaml(path)
    if not isinstance(data, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
        raise ConfigError("a segment map is a mapping `canonical name: segment name`", file=str(path))
    for k, v in data.items():
        if k not in MVN_SEGMENT_IDS:
            raise ConfigError(f"unknown canonical segment '{k}'; known: {', '.join(MVN_SEGMENT_IDS)}",
                              file=str(path), key=k)
        if segments is not None and v not in segments:
            raise ConfigError(f"the recording has no segment '{v}' (it has {', '.join(list(segments)[:8])}, ...)",
                              file=str(path), key=k)
    missing = [r for r in REQUIRED if r not in data]
    if missing:
        raise ConfigError(f"the segment map lacks {missing}", file=str(path))
    return SegmentMapping(dict(data), "file")
