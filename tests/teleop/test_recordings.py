"""The shipped synthetic recordings: registry, sizes, regeneration, content."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.errors import UnknownNameError
from wbcbench.teleop import generate_recordings, list_recordings, open_recording, parse_bvh, recording_path

EXPECTED = {
    "reach_forward", "reach_sideways", "waving", "crossing_arms", "arms_down", "head_turning", "bimanual_lift",
    "slow_circle", "push_pull",
}  # fmt: skip


def test_registry_lists_the_nine_recordings():
    """The 8 recordings of Table II (benchmarks/teleop_table2.py) and `push_pull` (paper Figure 2, at x2)."""
    infos = list_recordings()
    assert {i.name for i in infos} == EXPECTED
    for info in infos:
        assert info.description and info.path.is_file()
        assert info.path.stat().st_size < 200_000
        assert 10.0 <= info.duration <= 20.0 and 50.0 <= info.frame_rate <= 100.0


def test_regenerated_files_match_the_shipped_ones(tmp_path):
    """The shipped files are up to date with the generator (to the last written digit: platforms may round a
    value at the 0.005 boundary differently)."""
    paths = generate_recordings(tmp_path)
    assert {p.stem for p in paths} == EXPECTED
    for path in paths:
        new, shipped = parse_bvh(path), parse_bvh(recording_path(path.stem))
        assert new.skeleton == shipped.skeleton and new.frame_time == shipped.frame_time
        np.testing.assert_allclose(new.motion, shipped.motion, rtol=0, atol=0.0101, err_msg=path.name)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_recordings_read_back_with_feet_planted(name):
    rec = open_recording(name)
    info = next(i for i in list_recordings() if i.name == name)
    assert rec.duration == pytest.approx(info.duration)
    assert rec.frame_rate == pytest.approx(info.frame_rate)
    assert rec.has_joint_angles and len(rec.joint_names) == 39
    for foot in ("LeftFoot", "RightFoot"):
        p = rec.position(foot)
        assert np.ptp(p, axis=0).max() < 1e-3, f"{name}: {foot} moves"  # feet stay on the floor
    # starts and ends in the calibration posture: hands at the same place at both ends
    for hand in ("LeftHand", "RightHand"):
        p = rec.position(hand)
        np.testing.assert_allclose(p[0], p[-1], atol=2e-3)


def test_unknown_recording():
    with pytest.raises(UnknownNameError, match="arms_dwn.*arms_down"):
        open_recording("arms_dwn")
