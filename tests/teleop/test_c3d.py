"""C3D marker files (Plug-in Gait) through ezc3d: markers written here around a shipped recording's segments are
read back into the same segment origins, and a C3D clip drives TALOS end to end; bad C3D input is one line."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("ezc3d")

from wbcbench.errors import ConfigError  # noqa: E402
from wbcbench.teleop import read_bvh  # noqa: E402
from wbcbench.teleop._rotations import to_matrix  # noqa: E402
from wbcbench.teleop.io.c3d import marker_set, read_c3d, write_c3d  # noqa: E402
from wbcbench.teleop.loader import load_recording  # noqa: E402
from wbcbench.teleop.registry import recording_path  # noqa: E402

# the shipped recordings' world is y up; the C3D's is a Vicon-like z up: x' = x, y' = -z, z' = y
_TO_ZUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _perp(v, axis):
    return v - np.sum(v * axis, axis=-1, keepdims=True) * axis


def plug_in_gait_markers(name: str = "reach_forward", seconds: float = 3.0) -> tuple[dict, dict, float]:
    """Plug-in Gait markers (label -> (N, 3) [m], z up) placed around a shipped recording's joint centres, the
    joint centres themselves (canonical segment -> (N, 3), z up), and the frame rate."""
    rec = read_bvh(recording_path(name))
    n = int(round(seconds * rec.frame_rate))
    P = {s: rec.position(s)[:n] @ _TO_ZUP.T for s in rec.segments}
    R = {s: _TO_ZUP @ to_matrix(np.asarray(rec.orientations[:n, rec.segments.index(s)])) for s in rec.segments}
    up_world = np.array([0.0, 0.0, 1.0])
    hips_l, hips_r = P["LeftUpperLeg"], P["RightUpperLeg"]
    left = _unit(_perp(hips_l - hips_r, up_world[None]))
    up = np.tile(up_world, (n, 1))
    fwd = np.cross(left, up)
    # pelvis: invert Harrington's hip centres for a pelvis depth of 0.16 m
    sep = np.linalg.norm(hips_l - hips_r, axis=-1)
    pw = (sep / 2 - 0.0073) / 0.33
    pd = np.full(n, 0.16)
    mid = 0.5 * (hips_l + hips_r)
    asis = mid - (-0.24 * pd - 0.0099)[:, None] * fwd - (-0.30 * pw - 0.0109)[:, None] * up
    m = {"LASI": asis + 0.5 * pw[:, None] * left, "RASI": asis - 0.5 * pw[:, None] * left,
         "LPSI": asis - pd[:, None] * fwd + 0.05 * left, "RPSI": asis - pd[:, None] * fwd - 0.05 * left}
    t8 = P["T8"]
    m.update({"C7": t8 + 0.12 * up - 0.08 * fwd, "CLAV": t8 + 0.12 * up + 0.08 * fwd,
              "T10": t8 - 0.12 * up - 0.09 * fwd, "STRN": t8 - 0.12 * up + 0.09 * fwd})
    Rh = R["Head"]
    h_fwd, h_up = Rh[..., 0], Rh[..., 1]
    h_left = np.cross(h_up, h_fwd)
    hc = P["Head"] + 0.10 * h_up
    for tag, a, b in (("LFHD", 1, 1), ("RFHD", 1, -1), ("LBHD", -1, 1), ("RBHD", -1, -1)):
        m[tag] = hc + 0.08 * a * h_fwd + 0.07 * b * h_left
    for side, s, sign in (("Left", "L", 1.0), ("Right", "R", -1.0)):
        other = "Right" if side == "Left" else "Left"
        m[f"{s}SHO"] = P[f"{side}UpperArm"] + 0.05 * up
        elbow, shoulder = P[f"{side}ForeArm"], P[f"{side}UpperArm"]
        lateral = -_unit(_perp(t8 - elbow, _unit(shoulder - elbow)))
        m[f"{s}ELB"] = elbow + 0.042 * lateral
        Rw = R[f"{side}Hand"]
        m[f"{s}WRA"] = P[f"{side}Hand"] + 0.03 * Rw[..., 2]
        m[f"{s}WRB"] = P[f"{side}Hand"] - 0.03 * Rw[..., 2]
        m[f"{s}FIN"] = P[f"{side}Hand"] - 0.08 * Rw[..., 1]
        for joint, proximal, tag, r in (("LowerLeg", "UpperLeg", "KNE", 0.057), ("Foot", "LowerLeg", "ANK", 0.042)):
            c, prox, c_other = P[f"{side}{joint}"], P[f"{side}{proximal}"], P[f"{other}{joint}"]
            m[f"{s}{tag}"] = c - r * _unit(_perp(c_other - c, _unit(prox - c)))
        m[f"{s}TOE"] = P[f"{side}Foot"] + 0.14 * fwd - 0.06 * up
        m[f"{s}HEE"] = P[f"{side}Foot"] - 0.06 * fwd - 0.05 * up
        m[f"{s}THI"] = 0.5 * (P[f"{side}UpperLeg"] + P[f"{side}LowerLeg"]) + sign * 0.07 * left
    return m, P, rec.frame_rate


def test_markers_give_back_the_joint_centres(tmp_path):
    markers, P, rate = plug_in_gait_markers(seconds=2.0)
    path = write_c3d(tmp_path / "take.c3d", {f"Subject:{k}": v for k, v in markers.items()}, rate, units="mm")
    rec = read_c3d(path)
    assert rec.n_frames == len(P["Pelvis"]) and rec.frame_rate == pytest.approx(rate)
    for seg in ("T8", "LeftUpperArm", "LeftHand", "RightHand", "LeftUpperLeg", "RightUpperLeg"):
        err = np.linalg.norm(rec.position(seg) - P[seg], axis=1)
        assert err.max() < 2e-3, (seg, err.max())  # exact up to the C3D's float32 millimetres
    for seg in ("LeftForeArm", "RightLowerLeg", "LeftFoot", "Head"):
        err = np.linalg.norm(rec.position(seg) - P[seg], axis=1)
        assert err.max() < 0.01, (seg, err.max())  # the medial offsets are approximations of the chord function
    # a hand's frame turns with the hand: its rotations since the first frame are the recording's
    ref = read_bvh(recording_path("reach_forward"))
    R0 = to_matrix(np.asarray(rec.orientations[:, rec.segments.index("RightHand")]))
    R1 = np.einsum("ij,njk->nik", _TO_ZUP, to_matrix(np.asarray(
        ref.orientations[: rec.n_frames, ref.segments.index("RightHand")])))
    rel0 = np.einsum("nij,kj->nik", R0, R0[0])  # world-frame rotation since the first frame
    rel1 = np.einsum("nij,kj->nik", R1, R1[0])
    np.testing.assert_allclose(rel0, rel1, atol=2e-3)
    c = load_recording(path).conventions
    assert c["up"] == "+z" and c["unit_method"] == "file" and c["mapping"] == "names", c["line"]
    # the trunk's frames lie along the spine: T8's z from the neck down to T8, as every segment's z points from its
    # (first) child to it (an arm, T8's last child, is not its axis)
    for seg, child in (("T8", "Neck"), ("Neck", "Head"), ("LeftUpperArm", "LeftForeArm")):
        z = to_matrix(np.asarray(rec.orientations[:, rec.segments.index(seg)]))[..., 2]
        along = _unit(rec.position(seg) - rec.position(child))
        assert np.min(np.sum(z * along, axis=-1)) > 1 - 1e-9, seg


def test_the_cmu_hdm05_waist_marker_set_is_read_through_its_aliases(tmp_path):
    """The Vicon set of the CMU and HDM05 databases labels its pelvis markers on the waist belt (LFWT, RFWT, LBWT,
    RBWT) and adds others (RBAC, LUPA, LSHN, LMT5 ...): the same landmarks give the same segments, and the detection
    names the set; a file with neither ASIS nor waist markers still says which Plug-in Gait markers it lacks."""
    markers, _, rate = plug_in_gait_markers(seconds=1.0)
    waist = {"LASI": "LFWT", "RASI": "RFWT", "LPSI": "LBWT", "RPSI": "RBWT"}
    vicon = {f"Actor:{waist.get(k, k)}": v for k, v in markers.items()}
    vicon.update({"Actor:RBAC": markers["C7"], "Actor:LSHN": markers["LKNE"], "Actor:*0": markers["STRN"]})
    pig = read_c3d(write_c3d(tmp_path / "pig.c3d", markers, rate))
    rec = read_c3d(write_c3d(tmp_path / "vicon.c3d", vicon, rate))
    np.testing.assert_allclose(np.asarray(rec.positions), np.asarray(pig.positions), atol=1e-6)
    assert marker_set({k.split(":")[-1].upper() for k in vicon}) == "Vicon waist (CMU, HDM05)"
    assert marker_set(markers) == "Plug-in Gait" and marker_set({"C7", "T10"}) == "unknown"
    c = load_recording(tmp_path / "vicon.c3d").conventions
    assert c["naming"] == "Vicon waist (CMU, HDM05) markers" and c["up"] == "+z", c["line"]
    assert load_recording(tmp_path / "pig.c3d").conventions["naming"] == "Plug-in Gait markers"
    no_pelvis = {k: v for k, v in markers.items() if k not in waist}
    with pytest.raises(ConfigError, match="LASI"):
        read_c3d(write_c3d(tmp_path / "no_pelvis.c3d", no_pelvis, rate))


def test_a_c3d_clip_drives_talos_end_to_end(tmp_path):
    markers, _, rate = plug_in_gait_markers(seconds=4.0)
    path = write_c3d(tmp_path / "reach.c3d", markers, rate, units="mm")
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "teleop", "-i", str(path), "--out", str(out),
                           "--quiet"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "skeleton:" in proc.stdout.splitlines()[0]
    s = json.loads((out / "summary.json").read_text())
    m = s["metrics"]
    assert not s["fell"]
    assert m["hand_position_error_m"]["mean"] < 0.05, m["hand_position_error_m"]
    assert m.get("self_collisions", 0) == 0
    assert m["teleop"]["skeleton"]["conventions"]["up"] == "+z"


def test_a_c3d_without_the_markers_is_one_line(tmp_path):
    markers, _, rate = plug_in_gait_markers(seconds=0.5)
    for drop in ("LWRA", "RKNE"):
        path = write_c3d(tmp_path / f"no_{drop}.c3d", {k: v for k, v in markers.items() if k != drop}, rate)
        with pytest.raises(ConfigError, match=drop):
            read_c3d(path)
        proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "teleop", "-i", str(path), "--duration", "0.1",
                               "--out", str(tmp_path / drop)], capture_output=True, text=True)
        assert proc.returncode == 2 and drop in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, \
            proc.stderr
    bad = tmp_path / "garbage.c3d"
    bad.write_bytes(b"\x02P" + b"\x00" * 100)
    with pytest.raises(ConfigError, match="garbage.c3d"):
        read_c3d(bad)


def anatomical_markers(markers: dict, P: dict) -> dict:
    """The Plug-in Gait markers of `plug_in_gait_markers` relabelled as the anatomical-landmark set (the Rehazenter
    gait dataset's labels: L_IAS, CV7, SJN, L_SAE, L_HLE/L_HME, L_RSP/L_UHE, L_HM2/L_HM5, L_FLE/L_FME,
    L_FAL/L_TAM, L_FCC, L_FM1/L_FM2/L_FM5), with medial markers mirrored through the joint centres, no head
    markers."""
    out = {"CV7": markers["C7"], "TV10": markers["T10"], "SJN": markers["CLAV"], "SXS": markers["STRN"]}
    for side, s in (("Left", "L"), ("Right", "R")):
        out.update({f"{s}_IAS": markers[f"{s}ASI"], f"{s}_IPS": markers[f"{s}PSI"], f"{s}_SAE": markers[f"{s}SHO"],
                    f"{s}_RSP": markers[f"{s}WRA"], f"{s}_UHE": markers[f"{s}WRB"], f"{s}_FCC": markers[f"{s}HEE"],
                    f"{s}_HM2": markers[f"{s}FIN"] + 0.02 * (markers[f"{s}WRA"] - markers[f"{s}WRB"]),
                    f"{s}_HM5": markers[f"{s}FIN"] - 0.02 * (markers[f"{s}WRA"] - markers[f"{s}WRB"]),
                    f"{s}_FM2": markers[f"{s}TOE"], f"{s}_FM1": markers[f"{s}TOE"], f"{s}_FM5": markers[f"{s}TOE"]})
        for tag, lateral, medial, centre in (("ELB", "HLE", "HME", "ForeArm"), ("KNE", "FLE", "FME", "LowerLeg"),
                                             ("ANK", "FAL", "TAM", "Foot")):
            out[f"{s}_{lateral}"] = markers[f"{s}{tag}"]
            out[f"{s}_{medial}"] = 2.0 * P[f"{side}{centre}"] - markers[f"{s}{tag}"]
    return out


def test_the_anatomical_landmark_set_is_read_and_named(tmp_path):
    """The anatomical-landmark set (L_IAS, L_FLE, CV7, SJN ...) gives the Plug-in Gait set's segments from the same
    landmarks, its elbow, knee and ankle centres from the medial markers (exact where Plug-in Gait's are chord
    approximations), the head from the trunk when there are no head markers (said in the detection line); a file
    missing one of its markers is refused naming the marker in that set's labels."""
    markers, P, rate = plug_in_gait_markers(seconds=1.0)
    anat = anatomical_markers(markers, P)
    rec = read_c3d(write_c3d(tmp_path / "anat.c3d", {f"Subject:{k}": v for k, v in anat.items()}, rate))
    pig = read_c3d(write_c3d(tmp_path / "pig.c3d", markers, rate))
    for seg in ("Pelvis", "T8", "Neck", "LeftUpperArm", "RightHand", "LeftUpperLeg", "RightUpperLeg"):
        np.testing.assert_allclose(rec.position(seg), pig.position(seg), atol=2e-3, err_msg=seg)
    for seg in ("LeftForeArm", "RightForeArm", "LeftLowerLeg", "RightLowerLeg", "LeftFoot", "RightFoot"):
        err = np.linalg.norm(rec.position(seg) - P[seg], axis=1)
        assert err.max() < 2e-3, (seg, err.max())  # the epicondyles' / malleoli's midpoints: the centres
    # the head: the trunk's frame, above the neck; it follows the thorax, not the head's own turns
    head, neck = rec.position("Head"), rec.position("Neck")
    up = neck - rec.position("T8")
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", head - neck, up) > 0.05)
    assert marker_set({k.upper() for k in anat}) == "anatomical landmark (ISB)"
    c = load_recording(tmp_path / "anat.c3d").conventions
    assert c["naming"] == "anatomical landmark (ISB) markers" and c["up"] == "+z", c["line"]
    assert "head from the trunk" in c["line"] and c["notes"] == ["head from the trunk (no head markers)"]
    assert "head" not in load_recording(tmp_path / "pig.c3d").conventions["line"].split("rotation orders")[1]
    for drop in ("L_RSP", "R_FAL", "SJN"):
        path = write_c3d(tmp_path / f"no_{drop}.c3d", {k: v for k, v in anat.items() if k != drop}, rate)
        with pytest.raises(ConfigError, match=drop) as info:
            read_c3d(path)
        assert "anatomical landmark (ISB) markers" in str(info.value) and "\n" not in str(info.value)
