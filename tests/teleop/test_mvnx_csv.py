"""MVNX and pose-CSV readers: write then read, corrupted and truncated files, the suffix dispatcher."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.errors import ConfigError
from wbcbench.teleop import load_recording, read_mvnx, read_pose_csv, write_mvnx, write_pose_csv

from .conftest import assert_one_line_error, make_recording


def _same_poses(a, b, atol=1e-6):
    np.testing.assert_allclose(a.times, b.times, atol=1e-9)
    assert a.segments == b.segments
    np.testing.assert_allclose(a.positions, b.positions, atol=atol)
    # q and -q are the same rotation
    dots = np.abs(np.sum(a.orientations * b.orientations, axis=-1))
    np.testing.assert_allclose(dots, 1.0, atol=atol)


# ------------------------------------------------------------------------------------------------------ MVNX
def test_mvnx_round_trip(tmp_path):
    rec = make_recording(n=30, rate=60.0)
    path = write_mvnx(tmp_path / "take.mvnx", rec)
    back = read_mvnx(path)
    _same_poses(rec, back)
    assert back.frame_rate == 60.0
    assert back.joint_names == rec.joint_names
    np.testing.assert_allclose(back.joint_angles, rec.joint_angles, atol=1e-7)
    assert back.parents == (-1, -1, -1, -1)  # MVN parents of these four segments are absent from the file
    assert back.source == str(path) and back.up_axis == "z"


MVNX = """<?xml version="1.0" encoding="UTF-8"?>
<mvnx version="4" xmlns="http://www.xsens.com/mvn/mvnx">
<subject label="op" frameRate="100" segmentCount="2">
<segments>
<segment label="Pelvis" id="1"/>
<segment label="T8" id="5"/>
</segments>
<joints>
<joint label="jL5S1"/>
</joints>
<frames segmentCount="2" jointCount="1">
<frame time="0" index="-3" type="identity">
<orientation>1 0 0 0 1 0 0 0</orientation>
<position>0 0 0 0 0 0</position>
</frame>
<frame time="0" index="0" type="normal">
<orientation>1 0 0 0 0.7071068 0 0 0.7071068</orientation>
<position>0 0 0.9 0 0 1.2</position>
<jointAngle>1 2 3</jointAngle>
</frame>
<frame time="10" index="1" type="normal">
<orientation>1 0 0 0 1 0 0 0</orientation>
<position>0.1 0 0.9 0.1 0 1.2</position>
<jointAngle>4 5 6</jointAngle>
</frame>
</frames>
</subject>
</mvnx>
"""


def test_mvnx_sample_with_namespace_and_calibration_frames(tmp_path):
    path = tmp_path / "sample.mvnx"
    path.write_text(MVNX)
    rec = read_mvnx(path)
    assert rec.n_frames == 2  # the identity frame is skipped
    np.testing.assert_allclose(rec.times, [0.0, 0.01])
    assert rec.segments == ("Pelvis", "T8") and rec.parents == (-1, -1)
    # (w, x, y, z) in the file -> (x, y, z, w)
    np.testing.assert_allclose(rec.orientations[0, 1], [0.0, 0.0, 0.7071068, 0.7071068], atol=1e-6)
    assert rec.joint_names == ("jL5S1:x", "jL5S1:y", "jL5S1:z")
    np.testing.assert_allclose(rec.joint_angles[1], np.radians([4, 5, 6]))


MVNX_CORRUPTIONS = {
    "truncated": (MVNX[: MVNX.index("<jointAngle>4")], "line 24", "malformed XML"),
    "value count": (MVNX.replace("<position>0.1 0 0.9 0.1 0 1.2</position>", "<position>0.1 0 0.9 0.1 0</position>"),
                    "line 23", 'has 5 values, expected 6'),
    "frame element": (MVNX.replace('index="1" type="normal">', 'index="1" type="normal"> junk'), "", ""),
    "missing rate": (MVNX.replace(' frameRate="100"', ""), "line 3", "frameRate"),
    "no position": (MVNX.replace("<position>0.1 0 0.9 0.1 0 1.2</position>", ""), "line 21", "<position>"),
    "not unit": (MVNX.replace("<orientation>1 0 0 0 1 0 0 0</orientation>\n<position>0.1",
                              "<orientation>2 0 0 0 1 0 0 0</orientation>\n<position>0.1"),
                 "line 21", "non-unit quaternion"),
    "time backwards": (MVNX.replace('time="10"', 'time="0"'), "line 21", "does not increase"),
    "not a number": (MVNX.replace("<jointAngle>4 5 6", "<jointAngle>4 five 6"), "line 24", "non-number"),
    "wrong root": (MVNX.replace("<mvnx", "<bvh", 1).replace("</mvnx>", "</bvh>"), "line 2", "expected <mvnx>"),
    "no frames": (MVNX.replace('type="normal"', 'type="tpose"'), "line 11", "no frame of type 'normal'"),
}


@pytest.mark.parametrize("case", sorted(MVNX_CORRUPTIONS))
def test_mvnx_corrupted_files(tmp_path, case):
    text, line, fragment = MVNX_CORRUPTIONS[case]
    path = tmp_path / "broken.mvnx"
    path.write_text(text)
    if case == "frame element":  # stray text inside <frame> is harmless
        assert read_mvnx(path).n_frames == 2
        return
    with pytest.raises(ConfigError) as info:
        read_mvnx(path)
    assert_one_line_error(info, str(path), line, fragment)


# ------------------------------------------------------------------------------------------------------- CSV
def test_csv_round_trip(tmp_path):
    rec = make_recording(n=25, rate=100.0)
    path = write_pose_csv(tmp_path / "take.csv", rec)
    back = read_pose_csv(path)
    _same_poses(rec, back)
    assert back.frame_rate == pytest.approx(100.0)
    assert not back.has_joint_angles


CSV = """# wbcbench pose csv 1
# frame_rate: 50
t,segment,x,y,z,qx,qy,qz,qw
0.00,Pelvis,0,0,0.9,0,0,0,1
0.00,LeftHand,0.1,0.2,0.8,0,0,0,1
0.02,Pelvis,0,0,0.9,0,0,0,1
0.02,LeftHand,0.1,0.2,0.81,0,0,0.7071068,0.7071068
"""


def test_csv_sample_and_frame_rate_without_metadata(tmp_path):
    path = tmp_path / "sample.csv"
    path.write_text(CSV)
    rec = read_pose_csv(path)
    assert rec.segments == ("Pelvis", "LeftHand") and rec.n_frames == 2 and rec.frame_rate == 50.0
    assert rec.parents == (-1, -1)
    path.write_text(CSV.replace("# frame_rate: 50\n", ""))
    assert read_pose_csv(path).frame_rate == pytest.approx(50.0)


CSV_CORRUPTIONS = {
    "header": (CSV.replace("t,segment,x,y,z,qx,qy,qz,qw", "time,name,x,y,z,qw,qx,qy,qz"), "line 3", "header"),
    "truncated row": (CSV[:-20], "line 7", "columns"),
    "truncated frame": ("\n".join(CSV.splitlines()[:-1]) + "\n", "line 6", "lacks segments ['LeftHand']"),
    "backwards": (CSV.replace("0.02,Pelvis", "-0.02,Pelvis"), "line 6", "goes backwards"),
    "duplicate": (CSV.replace("0.00,LeftHand", "0.00,Pelvis"), "line 5", "appears twice"),
    "new segment": (CSV.replace("0.02,LeftHand", "0.02,RightHand"), "line 7", "not in the first frame"),
    "not a number": (CSV.replace("0.1,0.2,0.8", "0.1,abc,0.8"), "line 5", "'abc'"),
    "quaternion": (CSV.replace("0,0,0.7071068,0.7071068", "0,0,0,2"), "line 7", "quaternion norm"),
    "no header": ("# only a comment\n", "line 1", "no header"),
    "no data": ("t,segment,x,y,z,qx,qy,qz,qw\n", "line 1", "no data row"),
    "bad metadata": (CSV.replace("# frame_rate: 50", "# frame_rate: fast"), "", "frame_rate"),
}


@pytest.mark.parametrize("case", sorted(CSV_CORRUPTIONS))
def test_csv_corrupted_files(tmp_path, case):
    text, line, fragment = CSV_CORRUPTIONS[case]
    path = tmp_path / "broken.csv"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        read_pose_csv(path)
    assert_one_line_error(info, str(path), line, fragment)


# ---------------------------------------------------------------------------------------------- dispatcher
def test_load_recording_dispatches_on_suffix(tmp_path):
    rec = make_recording(n=5)
    write_pose_csv(tmp_path / "a.csv", rec)
    write_mvnx(tmp_path / "a.mvnx", rec)
    _same_poses(load_recording(tmp_path / "a.csv"), load_recording(tmp_path / "a.mvnx"))
    with pytest.raises(ConfigError) as info:
        load_recording(tmp_path / "a.fbx")
    assert_one_line_error(info, "a.fbx", "unknown recording format '.fbx'", ".bvh, .c3d, .csv, .mvnx")
    with pytest.raises(ConfigError) as info:
        load_recording(tmp_path / "missing.csv")
    assert_one_line_error(info, "missing.csv", "no such file")


def test_recording_validation_and_sampling():
    rec = make_recording(n=10, rate=10.0)
    frame = rec.frame_at(0.25)  # between frames 2 and 3
    assert frame.valid
    np.testing.assert_allclose(frame.positions["T8"], 0.5 * (rec.positions[2, 1] + rec.positions[3, 1]))
    assert np.linalg.norm(frame.orientations["T8"]) == pytest.approx(1.0)
    assert frame.joint_angles["jA:x"] == pytest.approx(0.5 * (rec.joint_angles[2, 0] + rec.joint_angles[3, 0]))
    held = rec.frame_at(5.0)
    assert not held.valid
    np.testing.assert_allclose(held.positions["T8"], rec.positions[-1, 1])
    with pytest.raises(ConfigError, match="strictly increasing"):
        type(rec)(source="x.csv", frame_rate=10.0, times=[0.0, 0.0], segments=("A",),
                  positions=np.zeros((2, 1, 3)), orientations=np.tile([0, 0, 0, 1.0], (2, 1, 1)))
    with pytest.raises(ConfigError, match="x.csv"):
        type(rec)(source="x.csv", frame_rate=10.0, times=[0.0, 0.1], segments=("A",),
                  positions=np.zeros((2, 1, 3)), orientations=np.zeros((2, 1, 4)))
    with pytest.raises(ConfigError, match="unknown segment 'Hed'.*Head|unknown segment 'Hed'"):
        rec.segment_index("Hed")
