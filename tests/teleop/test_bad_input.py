"""Bad recordings on the command line: one line naming the file and what is wrong, exit 2 (never a traceback)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from wbcbench.teleop.registry import recording_path

from .test_detection import write_skeleton


def _cli(path, tmp_path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "wbcbench.cli", "teleop", "-i", str(path), "--duration", "0.1",
                           "--out", str(tmp_path / "run"), "--quiet"], capture_output=True, text=True)


def _truncated(tmp_path):
    text = recording_path("reach_forward").read_text()
    path = tmp_path / "truncated.bvh"
    path.write_text(text[: len(text) // 2])  # cut inside a motion line
    return path, "truncated.bvh"


def _truncated_hierarchy(tmp_path):
    text = recording_path("reach_forward").read_text()
    path = tmp_path / "cut.bvh"
    path.write_text(text[: text.index("MOTION") // 2] + "\nMOTION\nFrames: 1\nFrame Time: 0.02\n0\n")
    return path, "cut.bvh"


def _nan(tmp_path):
    lines = recording_path("reach_forward").read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("Frame Time")) + 5
    values = lines[k].split()
    values[7] = "nan"
    lines[k] = " ".join(values)
    path = tmp_path / "nan.bvh"
    path.write_text("\n".join(lines) + "\n")
    return path, "finite"


def _one_arm(tmp_path):
    path = write_skeleton(tmp_path / "one_arm.bvh", "mixamo", drop=("rclavicle", "rshoulder", "relbow", "rwrist"))
    return path, "no right arm"


def _unknown_format(tmp_path):
    path = tmp_path / "take.fbx"
    path.write_bytes(b"Kaydara FBX Binary  \x00\x1a\x00")
    return path, ".fbx"


def _not_text(tmp_path):
    path = tmp_path / "binary.bvh"
    path.write_bytes(bytes(range(256)))
    return path, "binary.bvh"


def _c3d_without_markers(tmp_path):
    pytest.importorskip("ezc3d")
    from wbcbench.teleop.io.c3d import write_c3d

    from .test_c3d import plug_in_gait_markers

    markers, _, rate = plug_in_gait_markers(seconds=0.5)
    path = write_c3d(tmp_path / "no_wrist.c3d", {k: v for k, v in markers.items() if k != "RWRA"}, rate)
    return path, "RWRA"


@pytest.mark.parametrize("make", [_truncated, _truncated_hierarchy, _nan, _one_arm, _unknown_format, _not_text,
                                  _c3d_without_markers],
                         ids=lambda f: f.__name__.strip("_"))
def test_bad_recordings_are_one_line_and_exit_2(tmp_path, make):
    path, says = make(tmp_path)
    proc = _cli(path, tmp_path)
    err = proc.stderr.strip()
    assert proc.returncode == 2, err[-2000:]
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert path.name in err and says in err, err
