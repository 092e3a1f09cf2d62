"""An operator who walks and turns: with feet fixed (the default `auto` when the operator moves), the operator's
translation and yaw are taken out of the references; the robot stands and follows the upper body."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wbcbench.errors import ConfigError
from wbcbench.teleop import read_bvh
from wbcbench.teleop.human.locomotion import fix_feet
from wbcbench.teleop.io.bvh import parse_bvh, write_bvh
from wbcbench.teleop.registry import recording_path
from wbcbench.teleop.skeleton_map import map_segments


def _walk(t: np.ndarray, distance: float, turn_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(N,) yaw [rad] and (N, 3) translation (y-up world: forward along x) of a smooth walk and turn."""
    s = np.clip(t / t[-1], 0.0, 1.0)
    s = s * s * (3.0 - 2.0 * s)
    d = np.zeros((len(t), 3))
    d[:, 0] = distance * s
    return np.radians(turn_deg) * s, d


def write_walking(path, name: str = "reach_forward", seconds: float = 4.0, distance: float = 1.2,
                  turn_deg: float = 90.0):
    """A shipped recording with the operator walking `distance` metres and turning `turn_deg` about the vertical
    (the root's channels changed)."""
    data = parse_bvh(recording_path(name))
    n = int(round(seconds / data.frame_time))
    motion = np.array(data.motion[:n], dtype=float)
    root = data.skeleton.joints[0]
    cols = {ch: k for k, ch in enumerate(root.channels)}
    yaw, d = _walk(np.arange(n) * data.frame_time, distance, turn_deg)
    rot_channels = [ch for ch in root.channels if ch.endswith("rotation")]
    seq = "".join(ch[0] for ch in rot_channels)  # intrinsic, upper case
    R0 = Rotation.from_euler(seq, motion[:, [cols[c] for c in rot_channels]], degrees=True)
    R = Rotation.from_euler("Y", yaw[:, None]) * R0
    motion[:, [cols[c] for c in rot_channels]] = R.as_euler(seq, degrees=True)
    for axis, k in zip("XYZ", range(3)):
        motion[:, cols[f"{axis}position"]] += 100.0 * d[:, k]  # the file is in centimetres
    return write_bvh(path, data.skeleton, motion, data.frame_time, decimals=6)


def test_fixing_the_feet_undoes_a_walk(tmp_path):
    still = read_bvh(recording_path("reach_forward"))
    moved = read_bvh(write_walking(tmp_path / "walk.bvh"))
    names = map_segments(moved.segments, moved.parents).names
    fixed, motion = fix_feet(moved, names, "+y", "auto")
    assert motion.applied and motion.travel_m > 1.1 and motion.yaw_deg == pytest.approx(90.0, abs=1.0)
    n = fixed.n_frames
    np.testing.assert_allclose(fixed.positions, still.positions[:n], atol=2e-6)  # the file's 6 decimals
    dq = np.abs(np.sum(np.asarray(fixed.orientations) * np.asarray(still.orientations[:n]), axis=-1))
    assert np.all(dq > 1.0 - 1e-9)
    same, motion = fix_feet(still, names, "+y", "auto")  # an operator on the spot: untouched
    assert same is still and not motion.applied
    with pytest.raises(ConfigError, match="locomotion"):
        fix_feet(still, names, "+y", "walk")


def test_a_walking_operator_leaves_the_robot_standing(tmp_path):
    path = write_walking(tmp_path / "walk.bvh", seconds=4.0)
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "wbcbench.cli", "teleop", "-i", str(path), "--out", str(out),
                           "--quiet"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    s = json.loads((out / "summary.json").read_text())
    m = s["metrics"]
    assert not s["fell"]
    assert m["hand_position_error_m"]["mean"] < 0.05, m["hand_position_error_m"]
    assert m.get("self_collisions", 0) == 0
    om = m["teleop"]["skeleton"]["operator_motion"]
    assert om["applied"] and om["travel_m"] > 1.1, om
