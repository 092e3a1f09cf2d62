"""TRC marker files (OpenSim's text format) and OpenSim's gait marker set: markers written around a shipped
recording's joint centres are read back into them, through either label set; bad TRC input is one line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wbcbench.errors import ConfigError
from wbcbench.teleop import read_bvh
from wbcbench.teleop._rotations import to_matrix
from wbcbench.teleop.io.trc import read_trc, read_trc_markers, write_trc
from wbcbench.teleop.loader import load_recording
from wbcbench.teleop.registry import recording_path

# the shipped recording's world is y up, as OpenSim's; segments whose origins the markers give (the pelvis' is
# the ASIS mid-point, the recording's the hips')
_SEGMENTS = ("T8", "LeftUpperLeg", "RightUpperLeg", "LeftLowerLeg", "RightFoot", "LeftForeArm", "RightHand",
             "Head")


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _perp(v, axis):
    return v - np.sum(v * axis, axis=-1, keepdims=True) * axis


def opensim_markers(seconds: float = 2.0) -> tuple[dict, dict, float]:
    """OpenSim gait-set markers (label -> (N, 3) [m], y up) around the joint centres of the shipped `reach_forward`
    recording (medial and lateral markers either side of the knee and ankle centres), those centres, the rate."""
    rec = read_bvh(recording_path("reach_forward"))
    n = int(round(seconds * rec.frame_rate))
    P = {s: rec.position(s)[:n] for s in rec.segments}
    R = {s: to_matrix(np.asarray(rec.orientations[:n, rec.segments.index(s)])) for s in rec.segments}
    up = np.tile([0.0, 1.0, 0.0], (n, 1))
    left = _unit(_perp(P["LeftUpperLeg"] - P["RightUpperLeg"], up))
    fwd = np.cross(left, up)  # the pelvis frame: x forward, y left, z up
    # pelvis: Harrington's hip centres inverted for a pelvis depth of 0.16 m, the sacrum marker behind the ASIS
    pw = (np.linalg.norm(P["LeftUpperLeg"] - P["RightUpperLeg"], axis=-1) / 2 - 0.0073) / 0.33
    pd = np.full(n, 0.16)
    asis = (0.5 * (P["LeftUpperLeg"] + P["RightUpperLeg"]) - (-0.24 * pd - 0.0099)[:, None] * fwd
            - (-0.30 * pw - 0.0109)[:, None] * up)
    m = {"L.ASIS": asis + 0.5 * pw[:, None] * left, "R.ASIS": asis - 0.5 * pw[:, None] * left,
         "V.Sacral": asis - pd[:, None] * fwd}
    # the reader's T8 is half-way from the acromia's mid-point to the sternum marker
    m["Sternum"] = 2.0 * P["T8"] - (0.5 * (P["LeftUpperArm"] + P["RightUpperArm"]) + 0.05 * up)
    h_up, h_fwd = R["Head"][..., 1], R["Head"][..., 0]
    h_left = np.cross(h_up, h_fwd)
    m.update({"Top.Head": P["Head"] + 0.20 * h_up, "L.Temple": P["Head"] + 0.10 * h_up + 0.07 * h_left,
              "R.Temple": P["Head"] + 0.10 * h_up - 0.07 * h_left})
    for side, s in (("Left", "L"), ("Right", "R")):
        other = "Right" if side == "Left" else "Left"
        m[f"{s}.Acromium"] = P[f"{side}UpperArm"] + 0.05 * up
        elbow, shoulder = P[f"{side}ForeArm"], P[f"{side}UpperArm"]
        m[f"{s}.Elbow"] = elbow - 0.042 * _unit(_perp(P["T8"] - elbow, _unit(shoulder - elbow)))
        m[f"{s}.Wrist.Lat"] = P[f"{side}Hand"] + 0.03 * R[f"{side}Hand"][..., 2]
        m[f"{s}.Wrist.Med"] = P[f"{side}Hand"] - 0.03 * R[f"{side}Hand"][..., 2]
        for joint, name in (("LowerLeg", "Knee"), ("Foot", "Ankle")):
            lateral = _unit(P[f"{side}{joint}"] - P[f"{other}{joint}"])
            m[f"{s}.{name}.Lat"] = P[f"{side}{joint}"] + 0.05 * lateral
            m[f"{s}.{name}.Med"] = P[f"{side}{joint}"] - 0.05 * lateral
        m[f"{s}.Toe.Tip"] = P[f"{side}Foot"] + 0.18 * fwd - 0.06 * up
        m[f"{s}.Thigh.Upper"] = 0.5 * (P[f"{side}UpperLeg"] + P[f"{side}LowerLeg"]) + 0.07 * left
    return m, P, rec.frame_rate


def test_opensim_markers_give_back_the_joint_centres(tmp_path):
    markers, P, rate = opensim_markers()
    path = write_trc(tmp_path / "walk.trc", markers, rate, units="mm")
    rec = read_trc(path)
    assert rec.n_frames == len(P["Pelvis"]) and rec.frame_rate == pytest.approx(rate)
    for seg in _SEGMENTS:  # the medial and lateral markers give the knee and ankle centres exactly
        err = np.linalg.norm(rec.position(seg) - P[seg], axis=1)
        limit = 0.01 if seg == "LeftForeArm" else 1e-3  # the elbow's medial offset is the chord's approximation
        assert err.max() < limit, (seg, err.max())
    c = load_recording(path).conventions
    assert c["naming"] == "OpenSim gait (Gait2354) markers" and c["up"] == "+y" and c["unit_method"] == "file", \
        c["line"]
    # the same landmarks under Plug-in Gait labels in metres: the same segments (the thorax and head excepted)
    pig = {"L.ASIS": "LASI", "R.ASIS": "RASI", "V.Sacral": "SACR", "L.Acromium": "LSHO", "R.Acromium": "RSHO",
           "L.Elbow": "LELB", "R.Elbow": "RELB", "L.Wrist.Lat": "LWRA", "R.Wrist.Lat": "RWRA",
           "L.Wrist.Med": "LWRB", "R.Wrist.Med": "RWRB", "L.Knee.Lat": "LKNE", "R.Knee.Lat": "RKNE",
           "L.Knee.Med": "LKNM", "R.Knee.Med": "RKNM", "L.Ankle.Lat": "LANK", "R.Ankle.Lat": "RANK",
           "L.Ankle.Med": "LMED", "R.Ankle.Med": "RMED", "L.Toe.Tip": "LTOE", "R.Toe.Tip": "RTOE"}
    renamed = {f"Subject:{pig.get(k, k)}": v for k, v in markers.items()}
    other = read_trc(write_trc(tmp_path / "pig.trc", renamed, rate, units="m", decimals=6))
    for seg in ("Pelvis",) + _SEGMENTS[:-1]:
        np.testing.assert_allclose(other.position(seg), rec.position(seg), atol=2e-4)


def test_a_bad_trc_is_one_line(tmp_path):
    markers, _, rate = opensim_markers(seconds=0.5)
    good = write_trc(tmp_path / "good.trc", markers, rate)
    lines = good.read_text().splitlines()
    truncated = tmp_path / "truncated.trc"
    truncated.write_text("\n".join(lines[:-1] + [lines[-1][: len(lines[-1]) // 2]]) + "\n")
    with pytest.raises(ConfigError, match=f"line {len(lines)}.*truncated"):
        read_trc_markers(truncated)
    header_only = tmp_path / "header.trc"
    header_only.write_text("\n".join(lines[:2]) + "\n")
    with pytest.raises(ConfigError, match="header truncated: 2 line"):
        read_trc_markers(header_only)
    no_unit = tmp_path / "unit.trc"
    no_unit.write_text("\n".join(lines[:2] + [lines[2].replace("\tmm\t", "\tfurlong\t")] + lines[3:]) + "\n")
    with pytest.raises(ConfigError, match="furlong"):
        read_trc(no_unit)
    no_elbow = write_trc(tmp_path / "no_elbow.trc", {k: v for k, v in markers.items() if k != "R.Elbow"}, rate)
    with pytest.raises(ConfigError, match="R.ELBOW"):
        read_trc(no_elbow)
    for path, word in ((truncated, "truncated"), (no_elbow, "R.ELBOW")):
        proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "teleop", "-i", str(path), "--duration", "0.1",
                               "--out", str(tmp_path / path.stem)], capture_output=True, text=True)
        assert proc.returncode == 2 and word in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, \
            proc.stderr


def test_cast_markers_carries_the_static_knee_on_the_thigh_cluster(tmp_path):
    """tests/data/teleop/cast_markers.py (how the corpus' OpenSim walks got their knee and ankle markers): a static
    trial moved rigidly, frame by frame, without its knee and ankle markers, gets them back where the motion took
    them."""
    import importlib.util

    from scipy.spatial.transform import Rotation

    corpus = Path(__file__).resolve().parents[1] / "data" / "teleop"
    spec = importlib.util.spec_from_file_location("cast_markers", corpus / "cast_markers.py")
    cast = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cast)
    labels, xyz, rate = read_trc_markers(corpus / "opensim_static.trc")
    n = 40
    static = np.repeat(xyz[:1], n, axis=0)  # one standing frame of the corpus' static trial
    R = Rotation.from_rotvec(np.linspace([0.0, 0.0, 0.0], [0.3, -0.8, 0.2], n)).as_matrix()
    moved = np.einsum("nij,npj->npi", R, static) + np.linspace([0.0, 0.0, 0.0], [0.5, 0.1, -0.3], n)[:, None]
    carried = [k for k in labels if ".Knee." in k or ".Ankle." in k]
    write_trc(tmp_path / "static.trc", {k: static[:, i] for i, k in enumerate(labels)}, rate)
    write_trc(tmp_path / "motion.trc", {k: moved[:, i] for i, k in enumerate(labels) if k not in carried}, rate)
    assert cast.main([str(tmp_path / "static.trc"), str(tmp_path / "motion.trc"), str(tmp_path / "out.trc")]) == 0
    out_labels, out, _ = read_trc_markers(tmp_path / "out.trc")
    assert len(carried) == 8
    for k in carried:
        err = np.linalg.norm(out[:, out_labels.index(k)] - moved[:, labels.index(k)], axis=1)
        assert err.max() < 1e-6, (k, err.max())  # up to the files' 1e-4 mm
