"""Conventions found from the data, never from the file name: skeletons written here in each naming family, length
unit, up axis, forward direction and rest pose are detected as written; the shipped clips' detection is
unchanged; overrides win."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.teleop import BvhJoint, BvhSkeleton, write_bvh
from wbcbench.teleop.io.conventions import naming_family, rotation_orders
from wbcbench.teleop.loader import load_recording
from wbcbench.teleop.registry import list_recordings
from wbcbench.teleop.skeleton_map import map_segments

# a 1.72 m person in the canonical frame (z up, x forward, y left), metres; arms as given by the rest pose
_BODY = {
    "pelvis": (0.0, 0.0, 0.95), "spine": (0.0, 0.0, 1.08), "spine1": (0.0, 0.0, 1.20), "chest": (0.0, 0.0, 1.32),
    "neck": (0.0, 0.0, 1.50), "neck2": (0.0, 0.0, 1.55), "head": (0.0, 0.0, 1.60),
    "floor": (0.0, 0.0, 0.0),
}
for _s, _y in (("l", 1.0), ("r", -1.0)):
    _BODY.update({
        f"{_s}clavicle": (0.0, 0.03 * _y, 1.45), f"{_s}shoulder": (0.0, 0.18 * _y, 1.45),
        f"{_s}hipjoint": (0.0, 0.05 * _y, 0.93), f"{_s}hip": (0.0, 0.09 * _y, 0.92),
        f"{_s}knee": (0.0, 0.09 * _y, 0.50), f"{_s}ankle": (0.0, 0.09 * _y, 0.08), f"{_s}toe": (0.14, 0.09 * _y, 0.02),
    })

_ARM = (0.31, 0.25, 0.08)  # upper arm, forearm, hand [m]


def _body(rest: str) -> dict:
    """Joint positions with the arms in the rest pose: T (horizontal), A (45 deg from down) or down."""
    out = dict(_BODY)
    angle = {"T": 90.0, "A": 45.0, "down": 5.0}[rest]
    for s, y in (("l", 1.0), ("r", -1.0)):
        d = np.array([0.0, y * np.sin(np.radians(angle)), -np.cos(np.radians(angle))])
        p = np.array(out[f"{s}shoulder"])
        for name, length in zip(("elbow", "wrist", "hand"), _ARM):
            p = p + length * d
            out[f"{s}{name}"] = tuple(p)
    return out


def _sides(template: dict) -> dict:
    """A family's names: keys with {s} / {S} / {side} expanded for both sides."""
    out = {}
    for key, (name, parent) in template.items():
        if "{s}" in key:
            for s, S, side, sd in (("l", "L", "Left", "left"), ("r", "R", "Right", "right")):
                fmt = dict(s=s, S=S, side=side, sd=sd)
                out[key.format(**fmt)] = (name.format(**fmt), None if parent is None else parent.format(**fmt))
        else:
            out[key] = (name, parent)
    return out


# family -> {body point: (segment name, parent body point)}, in hierarchy order; the expected naming family; the
# body points the mapping must find for (hand, forearm, upper arm, foot, pelvis, thorax, head)
_ARM_LEG = {"{s}shoulder": ("", "{s}clavicle"), "{s}elbow": ("", "{s}shoulder"), "{s}wrist": ("", "{s}elbow"),
            "{s}hip": ("", "pelvis"), "{s}knee": ("", "{s}hip"), "{s}ankle": ("", "{s}knee"),
            "{s}toe": ("", "{s}ankle"), "{s}clavicle": ("", "chest")}


def _family(names: dict, extra: dict | None = None, spine=("spine", "chest", "neck", "head")) -> dict:
    out = {"pelvis": (names["pelvis"], None)}
    parent = "pelvis"
    for p in spine:
        out[p] = (names[p], parent)
        parent = p
    for key, (_, par) in _ARM_LEG.items():
        out[key] = (names[key], par)
    out.update(extra or {})
    return _sides(out)


FAMILIES = {
    "mvn": (_family({"pelvis": "Pelvis", "spine": "L5", "chest": "T8", "neck": "Neck", "head": "Head",
                     "{s}clavicle": "{side}Shoulder", "{s}shoulder": "{side}UpperArm", "{s}elbow": "{side}ForeArm",
                     "{s}wrist": "{side}Hand", "{s}hip": "{side}UpperLeg", "{s}knee": "{side}LowerLeg",
                     "{s}ankle": "{side}Foot", "{s}toe": "{side}Toe"}), "Xsens MVN"),
    "mixamo": (_family({"pelvis": "mixamorig:Hips", "spine": "mixamorig:Spine", "chest": "mixamorig:Spine2",
                        "neck": "mixamorig:Neck", "head": "mixamorig:Head",
                        "{s}clavicle": "mixamorig:{side}Shoulder", "{s}shoulder": "mixamorig:{side}Arm",
                        "{s}elbow": "mixamorig:{side}ForeArm", "{s}wrist": "mixamorig:{side}Hand",
                        "{s}hip": "mixamorig:{side}UpLeg", "{s}knee": "mixamorig:{side}Leg",
                        "{s}ankle": "mixamorig:{side}Foot", "{s}toe": "mixamorig:{side}ToeBase"}), "Mixamo"),
    # Blender / Rigify: .L/.R suffixes, spine.00N, the head not named head
    "rigify": (_family({"pelvis": "spine", "spine": "spine.001", "spine1": "spine.002", "chest": "spine.003",
                        "neck": "spine.004", "neck2": "spine.005", "head": "spine.006",
                        "{s}clavicle": "shoulder.{S}", "{s}shoulder": "upper_arm.{S}", "{s}elbow": "forearm.{S}",
                        "{s}wrist": "hand.{S}", "{s}hip": "thigh.{S}", "{s}knee": "shin.{S}",
                        "{s}ankle": "foot.{S}", "{s}toe": "toe.{S}"},
                       spine=("spine", "spine1", "chest", "neck", "neck2", "head")), "Blender/Rigify"),
    # SMPL joint names: left_shoulder is the upper arm, left_collar the clavicle
    "smpl": (_family({"pelvis": "pelvis", "spine": "spine1", "spine1": "spine2", "chest": "spine3", "neck": "neck",
                      "head": "head", "{s}clavicle": "{sd}_collar", "{s}shoulder": "{sd}_shoulder",
                      "{s}elbow": "{sd}_elbow", "{s}wrist": "{sd}_wrist", "{s}hip": "{sd}_hip",
                      "{s}knee": "{sd}_knee", "{s}ankle": "{sd}_ankle", "{s}toe": "{sd}_foot"},
                     spine=("spine", "spine1", "chest", "neck", "head")), "SMPL"),
    # 3ds Max Biped: a root at the floor, "Bip01 L Thigh" under the spine
    "biped": (_family({"pelvis": "Bip01 Pelvis", "spine": "Bip01 Spine", "chest": "Bip01 Spine2",
                       "neck": "Bip01 Neck", "head": "Bip01 Head", "{s}clavicle": "Bip01 {S} Clavicle",
                       "{s}shoulder": "Bip01 {S} UpperArm", "{s}elbow": "Bip01 {S} Forearm",
                       "{s}wrist": "Bip01 {S} Hand", "{s}hip": "Bip01 {S} Thigh", "{s}knee": "Bip01 {S} Calf",
                       "{s}ankle": "Bip01 {S} Foot", "{s}toe": "Bip01 {S} Toe0"}), "3ds Max Biped"),
    # CMU ASF names (lhumerus, lwrist ...), a hip joint bone between the root and the femur
    "cmu-asf": (_family({"pelvis": "root", "spine": "lowerback", "chest": "thorax", "neck": "lowerneck",
                         "head": "head", "{s}clavicle": "{s}clavicle", "{s}shoulder": "{s}humerus",
                         "{s}elbow": "{s}radius", "{s}wrist": "{s}wrist", "{s}hip": "{s}femur",
                         "{s}knee": "{s}tibia", "{s}ankle": "{s}foot", "{s}toe": "{s}toes",
                         "{s}hipjoint": "{s}hipjoint"},
                        extra={"{s}hipjoint": ("{s}hipjoint", "pelvis"), "{s}hip": ("{s}femur", "{s}hipjoint")}),
                "CMU ASF"),
    # Poser / Second Life (the BVH conversion of CMU's data for Second Life): lower-case side prefix, camel case
    "poser": (_family({"pelvis": "hip", "spine": "abdomen", "chest": "chest", "neck": "neck", "head": "head",
                       "{s}clavicle": "{s}Collar", "{s}shoulder": "{s}Shldr", "{s}elbow": "{s}ForeArm",
                       "{s}wrist": "{s}Hand", "{s}hip": "{s}Thigh", "{s}knee": "{s}Shin",
                       "{s}ankle": "{s}Foot", "{s}toe": "{s}Toe"}), "Poser/Second Life"),
    # side as a lower-case prefix
    "prefix": (_family({"pelvis": "hips", "spine": "spine", "chest": "chest", "neck": "neck", "head": "head",
                        "{s}clavicle": "{s}_clavicle", "{s}shoulder": "{s}_upperarm", "{s}elbow": "{s}_forearm",
                        "{s}wrist": "{s}_hand", "{s}hip": "{s}_thigh", "{s}knee": "{s}_calf",
                        "{s}ankle": "{s}_foot", "{s}toe": "{s}_toe"}), "generic"),
}
# canonical segment -> body point
_EXPECT = {"Pelvis": "pelvis", "T8": "chest", "Head": "head", "LeftHand": "lwrist", "LeftForeArm": "lelbow",
           "LeftUpperArm": "lshoulder", "RightHand": "rwrist", "RightFoot": "rankle", "RightLowerLeg": "rknee",
           "RightUpperLeg": "rhip"}
# file frames: canonical (z up, x forward) -> file axes
FRAMES = {"z-up": (np.eye(3), "+z", "+x"),
          "y-up": (np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]), "+y", "+z"),
          "y-up-x-back": (np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]), "+y", "-x")}


def write_skeleton(path, family: str, unit: float = 0.01, frame: str = "y-up", rest: str = "T", frames: int = 20,
                   drop=()):
    """A static BVH of `family`'s skeleton in `rest` pose, written in `unit` metres per file unit and `frame`."""
    spec = FAMILIES[family][0]
    body = _body(rest)
    M = FRAMES[frame][0]
    order: list[str] = []

    def visit(k):  # parents first
        parent = spec[k][1]
        if parent is not None and parent not in order:
            visit(parent)
        if k not in order:
            order.append(k)

    for k in spec:
        if k not in drop:
            visit(k)
    pos = {k: M @ np.asarray(body[k]) / unit for k in order}
    joints = []
    for k in order:
        name, parent = spec[k]
        if parent is None:
            joints.append(BvhJoint(name, -1, (0.0, 0.0, 0.0),
                                   ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")))
        else:
            joints.append(BvhJoint(name, order.index(parent), tuple(pos[k] - pos[parent]),
                                   ("Zrotation", "Xrotation", "Yrotation"),
                                   (0.0, 0.05 / unit, 0.0) if k == "head" else None))
    motion = np.zeros((frames, 6 + 3 * (len(order) - 1)))
    motion[:, :3] = pos[order[0]]
    motion[:, 0] += np.linspace(0.0, 0.05 / unit, frames)  # a little sway
    return write_bvh(path, BvhSkeleton(tuple(joints)), motion, 0.02, decimals=6)


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_each_naming_family_is_named_and_mapped(tmp_path, family):
    path = write_skeleton(tmp_path / "take.bvh", family)
    rec = load_recording(path)
    spec = FAMILIES[family][0]
    c = rec.conventions
    assert c["naming"] == FAMILIES[family][1], c["line"]
    mapping = map_segments(rec.segments, rec.parents, str(path))
    for canonical, point in _EXPECT.items():
        assert mapping.names[canonical] == spec[point][0], (family, canonical, mapping.names)
    assert c["unit_name"] == "cm" and c["up"] == "+y" and c["forward"] == "+z" and c["rest_pose"] == "T", c["line"]


@pytest.mark.parametrize("unit,name", [(1.0, "m"), (0.01, "cm"), (0.001, "mm"), (0.0254, "in"),
                                       (0.0254 / 0.45, "cmu-asf")])
@pytest.mark.parametrize("frame", sorted(FRAMES))
def test_unit_and_axes_are_detected(tmp_path, unit, name, frame):
    path = write_skeleton(tmp_path / "x.bvh", "mixamo", unit=unit, frame=frame, rest="A")
    rec = load_recording(path)
    c = rec.conventions
    _, up, forward = FRAMES[frame]
    assert (c["unit_name"], c["up"], c["forward"], c["rest_pose"]) == (name, up, forward, "A"), c["line"]
    assert c["unit_confidence"] > 0.9 and 1.55 < c["stature_m"] < 1.85, c["line"]
    assert rec.up_axis == up[-1]
    # positions come out in metres: the upper arm is 0.31 m long whatever the file's unit
    d = rec.position("mixamorig:LeftForeArm") - rec.position("mixamorig:LeftArm")
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), _ARM[0], rtol=1e-5)


def test_an_odd_scale_falls_back_to_the_stature(tmp_path):
    path = write_skeleton(tmp_path / "x.bvh", "mvn", unit=0.17, rest="down")  # no standard unit within x1.6
    c = load_recording(path).conventions
    assert c["unit_name"] == "" and c["unit_confidence"] == 0.0 and c["rest_pose"] == "other"
    assert c["stature_m"] == pytest.approx(1.70)


def test_rest_poses_and_overrides(tmp_path):
    for rest, expected in (("T", "T"), ("A", "A"), ("down", "other")):
        c = load_recording(write_skeleton(tmp_path / f"{rest}.bvh", "smpl", rest=rest)).conventions
        assert c["rest_pose"] == expected, c["line"]
    path = write_skeleton(tmp_path / "o.bvh", "smpl", unit=0.01, frame="z-up")
    rec = load_recording(path, length_unit="mm", up_axis="x")
    c = rec.conventions
    assert (c["unit_method"], c["unit_name"], c["up"], c["up_method"]) == ("given", "mm", "+x", "given")
    assert rec.length_unit_note.endswith("(given)")


def test_shipped_clips_detection_is_unchanged():
    """The shipped recordings (MVN names, centimetres, y up) are detected as such; the metres read are those of
    the reader at its default (centimetres)."""
    from wbcbench.teleop import read_bvh

    for info in list_recordings():
        rec = load_recording(info.path)
        c = rec.conventions
        assert (c["unit_name"], c["up"], c["naming"], c["mapping"]) == ("cm", "+y", "Xsens MVN", "names"), c["line"]
        assert c["unit_confidence"] > 0.99
        np.testing.assert_allclose(rec.positions, read_bvh(info.path).positions, rtol=1e-12, atol=1e-12)


def test_naming_family_and_rotation_orders_helpers():
    assert naming_family(["Hips", "LeftUpLeg", "LHipJoint", "LowerBack", "LeftArm"]) == "CMU"
    assert naming_family(["a", "b"]) == "generic"
    assert rotation_orders(["Hips:Zrotation", "Hips:Xrotation", "Hips:Yrotation", "A:Yrotation", "A:Xrotation",
                            "A:Zrotation", "B:Zrotation", "B:Xrotation", "B:Yrotation"]) == {"ZXY": 2, "YXZ": 1}


def test_the_start_line_names_what_was_detected(tmp_path, capsys):
    from wbcbench.teleop.commands import conventions_line

    path = write_skeleton(tmp_path / "take.bvh", "rigify", unit=1.0, frame="z-up")
    line = conventions_line(str(path))
    assert "\n" not in line and "Blender/Rigify" in line and "unit m " in line and "up +z" in line, line
    assert conventions_line("reach_forward") == "" and conventions_line("udp://127.0.0.1:9000") == ""
