"""Recordings in the common BVH skeleton conventions (CMU, Xsens BVH export, Mixamo, Bandai-Namco, Rokoko, Axis
Neuron) are read with no option: segments found by name or by the skeleton's chains, the length unit detected,
and the robot teleoperated from the command line. The fixtures are written here from a shipped recording, with
each convention's joint names, extra bones and length unit (not copies of any public file)."""

import json
import subprocess
import sys

import numpy as np
import pytest

from wbcbench.errors import ConfigError
from wbcbench.teleop.bvh import BvhJoint, BvhSkeleton, parse_bvh, write_bvh
from wbcbench.teleop.loader import load_recording
from wbcbench.teleop.mvnx import write_mvnx
from wbcbench.teleop.registry import recording_path
from wbcbench.teleop.skeleton_map import load_segment_map, map_segments

_SIDES = ("Left", "Right")

# each convention: the names of our 18 MVN segments, the extra bones (name, parent name), metres per file unit
CONVENTIONS = {
    # CMU (cgspeed conversions): LowerBack / Spine1, LeftArm, LeftUpLeg / LeftLeg; an unusual length unit
    "cmu": ({"Pelvis": "Hips", "L5": "LowerBack", "T8": "Spine1", "Head": "Head",
             **{f"{s}{a}": f"{s}{b}" for s in _SIDES for a, b in
                (("Shoulder", "Shoulder"), ("UpperArm", "Arm"), ("ForeArm", "ForeArm"), ("Hand", "Hand"),
                 ("UpperLeg", "UpLeg"), ("LowerLeg", "Leg"), ("Foot", "Foot"))}},
            [("LThumb", "LeftHand"), ("RThumb", "RightHand")], 0.0254 / 0.45),
    # Xsens MVN BVH export: LeftCollar -> LeftShoulder (the upper arm) -> LeftElbow -> LeftWrist; centimetres
    "xsens-bvh": ({"Pelvis": "Hips", "L5": "Chest", "T8": "Chest4", "Head": "Head",
                   **{f"{s}{a}": f"{s}{b}" for s in _SIDES for a, b in
                      (("Shoulder", "Collar"), ("UpperArm", "Shoulder"), ("ForeArm", "Elbow"), ("Hand", "Wrist"),
                       ("UpperLeg", "Hip"), ("LowerLeg", "Knee"), ("Foot", "Ankle"))}},
                  [], 0.01),
    # Mixamo: the mixamorig: prefix, fingers under the hands; centimetres
    "mixamo": ({"Pelvis": "mixamorig:Hips", "L5": "mixamorig:Spine", "T8": "mixamorig:Spine2",
                "Head": "mixamorig:Head",
                **{f"{s}{a}": f"mixamorig:{s}{b}" for s in _SIDES for a, b in
                   (("Shoulder", "Shoulder"), ("UpperArm", "Arm"), ("ForeArm", "ForeArm"), ("Hand", "Hand"),
                    ("UpperLeg", "UpLeg"), ("LowerLeg", "Leg"), ("Foot", "Foot"))}},
               [("mixamorig:LeftHandIndex1", "mixamorig:LeftHand"),
                ("mixamorig:RightHandIndex1", "mixamorig:RightHand")], 0.01),
    # Bandai-Namco motion dataset style: _L / _R suffixes; centimetres
    "bandai-namco": ({"Pelvis": "Hips", "L5": "Spine", "T8": "Chest", "Head": "Head",
                      **{f"{s}{a}": f"{b}_{s[0]}" for s in _SIDES for a, b in
                         (("Shoulder", "Shoulder"), ("UpperArm", "UpperArm"), ("ForeArm", "LowerArm"),
                          ("Hand", "Hand"), ("UpperLeg", "UpperLeg"), ("LowerLeg", "LowerLeg"), ("Foot", "Foot"))}},
                     [], 0.01),
    # Rokoko: LeftThigh / LeftShin, a forearm twist bone in the chain; metres
    "rokoko": ({"Pelvis": "Hips", "L5": "Spine1", "T8": "Spine4", "Head": "Head",
                **{f"{s}{a}": f"{s}{b}" for s in _SIDES for a, b in
                   (("Shoulder", "Shoulder"), ("UpperArm", "Arm"), ("ForeArm", "ForeArm"), ("Hand", "Hand"),
                    ("UpperLeg", "Thigh"), ("LowerLeg", "Shin"), ("Foot", "Foot"))}},
               [("LeftForeArmTwist", "LeftForeArm*"), ("RightForeArmTwist", "RightForeArm*")], 1.0),
    # Axis Neuron: Spine3, LeftUpLeg / LeftLeg; millimetres
    "axis-neuron": ({"Pelvis": "Hips", "L5": "Spine", "T8": "Spine3", "Head": "Head",
                     **{f"{s}{a}": f"{s}{b}" for s in _SIDES for a, b in
                        (("Shoulder", "Shoulder"), ("UpperArm", "Arm"), ("ForeArm", "ForeArm"), ("Hand", "Hand"),
                         ("UpperLeg", "UpLeg"), ("LowerLeg", "Leg"), ("Foot", "Foot"))}},
                    [], 0.001),
}


def write_convention(path, convention: str, recording: str = "reach_forward", seconds: float = 3.0):
    """The shipped recording (MVN names, centimetres) in a convention's names, bones and length unit."""
    names, extra, unit = CONVENTIONS[convention]
    data = parse_bvh(recording_path(recording))
    n = int(round(seconds / data.frame_time))
    scale = 0.01 / unit  # file units per centimetre
    src = data.skeleton.joints
    starts = np.cumsum([0] + [len(j.channels) for j in src])
    # name -> (parent name, offset, channels, end site, motion columns (n, k))
    bones = {}
    for k, j in enumerate(src):
        cols = np.array(data.motion[:n, starts[k]:starts[k + 1]], dtype=float)
        for c, ch in enumerate(j.channels):
            if ch.endswith("position"):
                cols[:, c] *= scale
        bones[names[j.name]] = [None if j.parent < 0 else names[src[j.parent].name], scale * np.asarray(j.offset),
                                j.channels, None if j.end_site is None else scale * np.asarray(j.end_site), cols]
    rot = ("Zrotation", "Xrotation", "Yrotation")
    for bone, parent in extra:
        if parent.endswith("*"):  # inserted into the chain: parent -> bone -> the parent's children
            parent = parent[:-1]
            for b in bones.values():
                if b[0] == parent:
                    b[0] = bone
            bones[bone] = [parent, np.zeros(3), rot, None, np.zeros((n, 3))]
        else:  # a leaf (a finger)
            bones[bone] = [parent, np.array([0.0, 3.0 * scale, 0.0]), rot, np.array([0.0, 2.0 * scale, 0.0]),
                           np.zeros((n, 3))]
    order = []

    def visit(name):
        if name not in order:
            if bones[name][0] is not None:
                visit(bones[name][0])
            order.append(name)

    for name in bones:
        visit(name)
    joints = tuple(BvhJoint(name, -1 if bones[name][0] is None else order.index(bones[name][0]),
                            tuple(bones[name][1]), bones[name][2],
                            None if bones[name][3] is None else tuple(bones[name][3])) for name in order)
    motion = np.hstack([bones[name][4] for name in order])
    return write_bvh(path, BvhSkeleton(joints), motion, data.frame_time, decimals=6)


@pytest.mark.parametrize("convention", sorted(CONVENTIONS))
def test_each_convention_maps_every_segment_and_its_unit(tmp_path, convention):
    path = write_convention(tmp_path / f"{convention}.bvh", convention)
    rec = load_recording(path)
    mapping = map_segments(rec.segments, rec.parents, str(path))
    names = CONVENTIONS[convention][0]
    for canonical in ("LeftHand", "RightHand", "LeftForeArm", "LeftUpperArm", "RightUpperLeg", "LeftFoot", "Head",
                      "Pelvis", "T8"):
        assert mapping.names[canonical] == names[canonical], (convention, canonical, mapping.names[canonical])
    # the unit: the recording's segments at their true size (the shipped file in centimetres)
    ref = load_recording(recording_path("reach_forward"))
    upper = [np.median(np.linalg.norm(r.position(m["LeftForeArm"]) - r.position(m["LeftUpperArm"]), axis=1))
             for r, m in ((rec, names), (ref, {k: k for k in names}))]
    assert upper[0] == pytest.approx(upper[1], rel=0.05) if convention != "cmu" else 0.5 < upper[0] / upper[1] < 2.0
    assert rec.length_unit_note


@pytest.mark.parametrize("convention", sorted(CONVENTIONS) + ["mvnx"])
def test_a_convention_teleoperates_talos_from_the_command_line(tmp_path, convention):
    """Every convention, and the shipped recording exported as Xsens MVNX: with no option, the robot follows
    (hand error under 5 cm), stands, and the grippers touch nothing."""
    if convention == "mvnx":
        path = write_mvnx(tmp_path / "take.mvnx", load_recording(recording_path("reach_forward")))
    else:
        path = write_convention(tmp_path / f"{convention}.bvh", convention)
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "teleop", "-i", str(path), "--out", str(out),
                           "--quiet"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    s = json.loads((out / "summary.json").read_text())
    m = s["metrics"]
    assert not s["fell"]
    assert m["hand_position_error_m"]["mean"] < 0.05
    assert m.get("self_collisions", 0) == 0
    if convention != "mvnx":  # MVNX states positions in metres: nothing to detect
        assert m["teleop"]["skeleton"]["length_unit"]


def test_segment_map_file_and_its_errors(tmp_path):
    path = write_convention(tmp_path / "x.bvh", "bandai-namco")
    rec = load_recording(path)
    names = CONVENTIONS["bandai-namco"][0]
    good = tmp_path / "map.yaml"
    good.write_text("\n".join(f"{k}: {v}" for k, v in names.items()))
    assert load_segment_map(good, rec.segments).names["LeftHand"] == "Hand_L"
    bad = tmp_path / "bad.yaml"
    bad.write_text("\n".join(f"{k}: {v}" for k, v in {**names, "LeftHand": "Hand_X"}.items()))
    with pytest.raises(ConfigError, match="Hand_X"):
        load_segment_map(bad, rec.segments)
    unknown = tmp_path / "unknown.yaml"
    unknown.write_text("LeftPaw: Hand_L\n")
    with pytest.raises(ConfigError, match="LeftPaw"):
        load_segment_map(unknown, rec.segments)
    proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "teleop", "-i", str(path), "--segment-map",
                           str(bad), "--duration", "0.1", "--out", str(tmp_path / "r")], capture_output=True, text=True)
    assert proc.returncode == 2 and "Hand_X" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_impossible_units_and_unnamed_skeletons_are_one_line_errors(tmp_path):
    path = write_convention(tmp_path / "x.bvh", "mixamo")
    for unit in ("-1", "furlong", "0"):
        proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "teleop", "-i", str(path), "--length-unit", unit,
                               "--duration", "0.1", "--out", str(tmp_path / unit)], capture_output=True, text=True)
        assert proc.returncode == 2 and "length" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    segments = ("root", "a", "b", "c")
    with pytest.raises(ConfigError, match="segment-map"):
        map_segments(segments, (-1, 0, 1, 2), "x.bvh")
