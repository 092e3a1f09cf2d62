"""A recording's conventions, found from its data (never from the file name): length unit, up and forward axes,
rotation order per joint, rest pose and the segment naming family.

* Length unit: the operator's stature is estimated in file units from the skeleton, in two ways: the standing
  extent (95th percentile over the frames of the joints' extent along the up axis, ankle or toe to head joint,
  about 0.94 of the stature) and, when the segments are identified, the limbs' lengths against adult proportions
  (upper arm 0.186, forearm 0.146, thigh 0.245, shank 0.246 of the stature; Winter, *Biomechanics and Motor
  Control of Human Movement*, 4th ed., Fig. 4.1); the limb lengths are medians over the frames, so that a sitting
  or crouching operator does not shrink. The unit is the standard one (m, dm, cm, mm, in, ft, and the CMU
  database's 1/0.45 inch) that puts the
  stature closest to an adult's 1.70 m, if one is within a factor 1.6; else the scale that makes it 1.70 m. Its
  confidence is that unit's posterior probability among the standard units under a log-normal prior on the
  stature (sigma 0.15 in log, or the estimates' spread if larger).
* Up axis: the mean direction from the feet to the head, and the legs' (upper leg to foot) direction, over the
  frames: the signed file axis nearest to it (without identified segments: the axis of largest extent, +).
  Forward: left x up, with left from the right to the left hip and shoulder.
* Rotation order: per joint, the order of its BVH rotation channels (``R = R_ch1 R_ch2 R_ch3``, read as given).
* Rest pose: the skeleton at zero joint angles (BVH offsets; the first frame for formats without a hierarchy
  pose): the upper arms' angle from the down direction: "T" (above 70 deg), "A" (20 to 70 deg), else "other".
* Naming family: from the segment names (Xsens MVN, Xsens BVH export, CMU, CMU ASF, Mixamo, 3ds Max Biped,
  Blender/Rigify, SMPL, Bandai-Namco, Poser/Second Life, generic), informative; the mapping to the canonical
  segments is by names, then by the hierarchy (:mod:`.skeleton_map`).

`--length-unit`, `--up-axis` and `--segment-map` override what is detected.
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

__all__ = ["HUMAN_STATURE", "Conventions", "detect_conventions", "naming_family",
           "rotation_orders", "stature_estimates", "up_vector"]

#: Length units a file may use: name -> metres per unit ("cmu-asf": the CMU database's ASF unit, 1/0.45 inch,
#: kept by BVH conversions of it).
LENGTH_UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048, "cmu-asf": 0.0254 / 0.45}
#: [m] the stature the unit detection assumes (adult).
HUMAN_STATURE = 1.70
#: standing extent (ankle or toe to head joint) / stature
_EXTENT_RATIO = 1.6 / HUMAN_STATURE
#: limb (proximal segment, distal segment) -> its length / stature (Winter, Fig. 4.1)
_PROPORTIONS = {("UpperArm", "ForeArm"): 0.186, ("ForeArm", "Hand"): 0.146, ("UpperLeg", "LowerLeg"): 0.245,
                ("LowerLeg", "Foot"): 0.246}
_SIGMA = 0.15
_STANDARD_WITHIN = np.log(1.6)


@dataclass(frozen=True)
class Conventions:
    """What a recording's data says about its conventions (module docstring); lengths in metres.

    Attributes:
        length_unit: metres per file unit.
        unit_name: the standard unit's name, "" for a bare scale.
        unit_method: "detected", "given" or "file" (a format whose unit is fixed, e.g. MVNX metres).
        stature_m: the operator's estimated stature with that unit [m] (nan when the unit was not detected).
        unit_confidence: posterior probability of the unit among the standard units, in [0, 1] (1 when given).
        stature_estimates: name -> estimate [m] (standing extent, limb lengths) with that unit.
        up: signed axis ("+y", "-z" ...) of the file's world frame that points up; `up_method` says how.
        forward: signed axis the operator faces ("" if unknown).
        rest_pose: "T", "A" or "other" (with the upper arms' angle from down, `arm_angle_deg`).
        rotation_orders: order -> number of joints (e.g. {"ZXY": 20, "ZYX": 1}); empty without joint angles.
        naming: the naming family.
        mapping: how the canonical segments were found ("names", "topology", "file") or "" if not.
        notes: what else the reader had to decide (e.g. a marker file's head taken from its trunk), on the line.
    """

    length_unit: float
    unit_name: str
    unit_method: str
    stature_m: float
    unit_confidence: float
    up: str
    up_method: str
    forward: str
    rest_pose: str
    arm_angle_deg: float
    rotation_orders: Mapping[str, int]
    naming: str
    mapping: str
    stature_estimates: Mapping[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    @property
    def up_axis(self) -> str:
        """The unsigned up axis ("x", "y" or "z")."""
        return self.up[-1]

    def line(self) -> str:
        """One line for the console: what was detected (or given)."""
        if self.unit_method == "detected":
            unit = (f"{self.unit_name or f'{self.length_unit:.4g} m per unit'} (stature {self.stature_m:.2f} m, "
                    f"confidence {self.unit_confidence:.2f})")
        else:
            unit = f"{self.unit_name or f'{self.length_unit:.4g} m per unit'} ({self.unit_method})"
        orders = ", ".join(f"{o} x{n}" for o, n in self.rotation_orders.items()) or "-"
        rest = f"{self.rest_pose}-pose ({self.arm_angle_deg:.0f} deg)" if np.isfinite(self.arm_angle_deg) else "-"
        return (f"skeleton: {self.naming} names ({self.mapping or 'unmapped'}); unit {unit}; up {self.up} "
                f"({self.up_method}); forward {self.forward or '?'}; rest {rest}; rotation orders {orders}"
                + "".join(f"; {n}" for n in self.notes))

    def as_dict(self) -> dict:
        """Plain values (for summary.json)."""
        d = asdict(self)
        d["rotation_orders"] = dict(self.rotation_orders)
        d["stature_estimates"] = dict(self.stature_estimates)
        d["notes"] = list(self.notes)
        d = {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in d.items()}
        d["line"] = self.line()
        return d


# ------------------------------------------------------------------------------------------------------- naming
_FAMILIES: tuple[tuple[str, re.Pattern], ...] = (
    ("Mixamo", re.compile(r"^mixamorig\d*:", re.I)),
    ("3ds Max Biped", re.compile(r"^bip0*1([ _]|$)", re.I)),
    ("Blender/Rigify", re.compile(r"(\.[LRlr](\.\d+)?$|^(def|org|mch)-|^spine\.\d{3}$)")),
    ("SMPL", re.compile(r"^(left|right)_(collar|wrist|elbow|knee|ankle|hip)$|^spine[123]$")),
    ("Xsens MVN", re.compile(r"^(L5|L3|T12|T8|(Left|Right)(UpperArm|ForeArm|UpperLeg|LowerLeg))$")),
    ("Xsens BVH", re.compile(r"^(Left|Right)(Collar|Elbow|Wrist)$|^Chest[234]$")),
    ("CMU ASF", re.compile(r"^[lr](humerus|radius|femur|tibia|clavicle)$|^(upper|lower)back$", re.I)),
    ("CMU", re.compile(r"^([LR]HipJoint|LowerBack|(Left|Right)(FingerBase|HandIndex1?))$|^[LR]Thumb$")),
    ("Bandai-Namco", re.compile(r"^(UpperArm|LowerArm|UpperLeg|LowerLeg|Hand|Foot|Shoulder)_[LR]$")),
    ("Poser/Second Life", re.compile(r"^(hip|abdomen|[lr](Collar|Shldr|ForeArm|Hand|Buttock|Thigh|Shin|Foot))$")),
    ("Rokoko/Axis Neuron", re.compile(r"^(Left|Right)(Thigh|Shin|UpLeg|Leg|Arm|ForeArm)$")),
)


#: names several families share (CMU, Mixamo without its prefix, Rokoko, Axis Neuron: LeftUpLeg, LeftArm ...) count
#: less than a family's own
_SHARED = ("Rokoko/Axis Neuron",)


def naming_family(segments: Sequence[str]) -> str:
    """The naming family whose patterns match most segment names, a family's own names counting five times the
    names several families share (ties: the first in the table), else "generic"."""
    best, score = "generic", 0
    for family, pattern in _FAMILIES:
        n = sum(1 for s in segments if pattern.search(s.strip())) * (1 if family in _SHARED else 5)
        if n > score:
            best, score = family, n
    return best


def rotation_orders(joint_names: Sequence[str]) -> dict[str, int]:
    """Rotation order -> number of joints, from joint-angle channel names ``"<joint>:<X|Y|Z>rotation"`` in file
    order (MVNX's ``"<joint>:<x|y|z>"`` give the order as listed)."""
    per_joint: dict[str, str] = {}
    for name in joint_names:
        joint, _, ch = name.rpartition(":")
        if ch and ch[0].lower() in "xyz":
            per_joint[joint] = per_joint.get(joint, "") + ch[0].upper()
    return dict(Counter(per_joint.values()).most_common())


# ------------------------------------------------------------------------------------------------- geometry
def up_vector(up: str) -> np.ndarray:
    """The unit vector (3,) of a signed axis name ("+y", "-z", ...), e.g. a recording's up axis."""
    return np.eye(3)["xyz".index(up[-1])] * (1.0 if up[0] == "+" else -1.0)


def _axis_name(v: np.ndarray) -> str:
    k = int(np.argmax(np.abs(v)))
    return ("+" if v[k] >= 0 else "-") + "xyz"[k]


def _positions(recording, names: Mapping[str, str], key: str) -> np.ndarray | None:
    seg = names.get(key)
    return None if seg is None or seg not in recording.segments else np.asarray(recording.position(seg))


def stature_estimates(recording, names: Mapping[str, str] | None, up_axis: int) -> dict[str, float]:
    """Stature estimates in file units (module docstring): "extent" and, with a mapping, one per limb segment."""
    P = np.asarray(recording.positions, dtype=float)
    finite = np.isfinite(P).all(axis=2)
    ext = np.array([np.ptp(P[i, finite[i], up_axis]) if finite[i].any() else 0.0 for i in range(P.shape[0])])
    out = {"extent": float(np.percentile(ext, 95)) / _EXTENT_RATIO}
    if names:
        for side in ("Left", "Right"):
            for (a, b), ratio in _PROPORTIONS.items():
                pa, pb = _positions(recording, names, side + a), _positions(recording, names, side + b)
                if pa is not None and pb is not None:
                    d = np.linalg.norm(pb - pa, axis=1)
                    d = d[np.isfinite(d)]
                    if d.size and np.median(d) > 0:
                        out[f"{side[0].lower()}_{a.lower()}"] = float(np.median(d)) / ratio
    return out


def _choose_unit(statures: Mapping[str, float]) -> tuple[float, str, float, float]:
    """(metres per unit, unit name or "", stature [m], confidence) from stature estimates in file units."""
    values = np.array([v for v in statures.values() if np.isfinite(v) and v > 0])
    if values.size == 0:
        return float("nan"), "", float("nan"), 0.0
    logs = np.log(values)
    h = float(np.exp(np.median(logs)))
    spread = float(np.std(logs)) if values.size > 1 else 0.0
    sigma = max(_SIGMA, spread)
    dev = {n: np.log(h * u / HUMAN_STATURE) for n, u in LENGTH_UNITS.items()}
    weights = {n: np.exp(-0.5 * (d / sigma) ** 2) for n, d in dev.items()}
    name = min(dev, key=lambda n: abs(dev[n]))
    if abs(dev[name]) <= _STANDARD_WITHIN:
        total = sum(weights.values())
        return LENGTH_UNITS[name], name, h * LENGTH_UNITS[name], float(weights[name] / total) if total else 0.0
    unit = HUMAN_STATURE / h
    return unit, "", HUMAN_STATURE, 0.0


def _rest_positions(recording, skeleton) -> np.ndarray:
    """(S, 3) the skeleton's segment positions at zero joint angles (file units): the BVH offsets, else the
    recording's first frame."""
    if skeleton is not None:
        zero = np.zeros((1, skeleton.channel_count))
        p, _ = skeleton.forward_kinematics(zero)
        return p[0]
    return np.asarray(recording.positions[0], dtype=float)


def detect_conventions(recording, *, skeleton=None, mapping=None, length_unit: float | None = None,
                       up_axis: str = "auto", unit_method: str = "detected") -> Conventions:
    """The conventions of a recording read in file units (module docstring).

    Args:
        recording: a :class:`~wbcbench.teleop.MocapRecording` in file units.
        skeleton: its :class:`~wbcbench.teleop.BvhSkeleton` (for the rest pose), if any.
        mapping: a :class:`~.skeleton_map.SegmentMapping` of its segments, or None (then only the extent gives
            the unit, and the up axis is the axis of largest extent).
        length_unit: metres per unit if given (not detected); `unit_method` says how it is known.
        up_axis: "auto" or a given axis "x", "y", "z" (taken as +).
    """
    names = dict(mapping.names) if mapping is not None else {}
    P = np.asarray(recording.positions, dtype=float)
    # --- up
    up_vec = None
    head, pelvis = _positions(recording, names, "Head"), _positions(recording, names, "Pelvis")
    feet = [f for f in (_positions(recording, names, "LeftFoot"), _positions(recording, names, "RightFoot"))
            if f is not None]
    if up_axis in ("x", "y", "z"):
        up, up_method = "+" + up_axis, "given"
        up_vec = np.eye(3)["xyz".index(up_axis)]
    elif head is not None and pelvis is not None and feet:
        foot = np.mean(feet, axis=0)
        v = np.nanmean((head - foot) / np.linalg.norm(head - foot, axis=1, keepdims=True), axis=0)
        v = v + np.nanmean((pelvis - foot) / np.linalg.norm(pelvis - foot, axis=1, keepdims=True), axis=0)
        up, up_method = _axis_name(v), "feet to head"
        up_vec = up_vector(up)
    else:
        finite = np.isfinite(P).all(axis=2)
        ext = np.array([[np.ptp(P[i, finite[i], a]) if finite[i].any() else 0.0 for a in range(3)]
                        for i in range(P.shape[0])])
        k = int(np.argmax(np.median(ext, axis=0)))
        up, up_method = "+" + "xyz"[k], "largest extent"
        up_vec = np.eye(3)[k]
    # --- forward: left x up
    forward = ""
    lefts = []
    for a in ("UpperLeg", "UpperArm"):
        pl, pr = _positions(recording, names, "Left" + a), _positions(recording, names, "Right" + a)
        if pl is not None and pr is not None:
            lefts.append(np.nanmean(pl - pr, axis=0))
    if lefts:
        left = np.sum(lefts, axis=0)
        left = left - np.dot(left, up_vec) * up_vec
        if np.linalg.norm(left) > 0:
            forward = _axis_name(np.cross(left, up_vec))
    # --- unit
    statures = stature_estimates(recording, names, "xyz".index(up[-1]))
    if length_unit is None:
        unit, unit_name, stature, confidence = _choose_unit(statures)
    else:
        unit = float(length_unit)
        unit_name = next((n for n, u in LENGTH_UNITS.items() if u == unit), "")
        stature, confidence = float(np.median(list(statures.values()))) * unit, 1.0
    # --- rest pose
    arm_angle = float("nan")
    rest = "other"
    if names:
        R = _rest_positions(recording, skeleton)
        index = {s: i for i, s in enumerate(recording.segments)}
        angles = []
        for side in ("Left", "Right"):
            a, b = names.get(side + "UpperArm"), names.get(side + "ForeArm")
            if a in index and b in index:
                v = R[index[b]] - R[index[a]]
                if np.linalg.norm(v) > 0:
                    angles.append(np.degrees(np.arccos(np.clip(np.dot(v, -up_vec) / np.linalg.norm(v), -1, 1))))
        if angles:
            arm_angle = float(np.mean(angles))
            rest = "T" if arm_angle > 70.0 else "A" if arm_angle >= 20.0 else "other"
    return Conventions(
        length_unit=unit, unit_name=unit_name, unit_method=unit_method if length_unit is None else unit_method,
        stature_m=float(stature), unit_confidence=float(confidence), up=up, up_method=up_method, forward=forward,
        rest_pose=rest, arm_angle_deg=arm_angle, rotation_orders=rotation_orders(recording.joint_names),
        naming=naming_family(recording.segments), mapping=mapping.method if mapping is not None else "",
        stature_estimates={k: v * unit for k, v in statures.items()},
    )
