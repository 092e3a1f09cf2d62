"""Rendering runs (wbcbench/viz/render.py): an MP4 that decodes to the right frames with the robot in them, a
walk that moves across a fixed camera's image, visual meshes that change nothing in the simulation, and bad
input answered in one line."""

import subprocess
import sys

import av
import numpy as np
import pytest

from wbcbench.runner import run
from wbcbench.sim.model import VISUAL_GROUP, SimOptions
from wbcbench.viz.render import Overlays, _Frames, _plan, _Renderer, _render_replay, keyframe_strip, render_run

from .conftest import bad_run_dirs


def _decode(path):
    with av.open(str(path)) as c:
        return [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]


def _robot_mask(run_dir, frame, time_s, camera, size):
    """Pixels of a decoded frame that differ from the same view rendered without the robot (H.264 tolerant)."""
    replay = _render_replay(run_dir)
    r = _Renderer(replay, size[0], size[1], camera, Overlays.none())
    r.options.geomgroup[VISUAL_GROUP] = 0
    empty = r.frame(time_s)
    r.close()
    return (np.abs(frame.astype(int) - empty.astype(int)).max(axis=2) > 40)


@pytest.fixture(scope="module")
def stand_run(tmp_path_factory):
    return run("stand", "tsid-torque", duration=1.0, out=tmp_path_factory.mktemp("r") / "stand").run_dir


def test_one_second_of_stand_to_mp4(stand_run, tmp_path):
    out = render_run(stand_run, tmp_path / "s.mp4", size="320x240", fps=30, overlays=Overlays.none())
    frames = _decode(out)
    assert abs(len(frames) - 31) <= 1  # 0, 1/30, ..., 1 s
    assert frames[0].shape == (240, 320, 3)
    robot = _robot_mask(stand_run, frames[0], 0.0, "follow", (320, 240))
    assert robot.mean() > 0.02  # the robot covers a real part of the image, not a blank frame
    slow = _decode(render_run(stand_run, tmp_path / "slow.mp4", size="160x120", fps=10, speed=0.5, workers=2))
    assert abs(len(slow) - 21) <= 1  # 2 s of video for 1 s at half speed


def test_a_walk_moves_across_a_fixed_camera(tmp_path):
    res = run("walk-20cm-quick", "tsid-torque", duration=5.0, out=tmp_path / "w")  # 0.38 m forward by 5 s
    out = render_run(res.run_dir, tmp_path / "w.mp4", size="320x240", fps=10, camera="top", overlays=Overlays.none())
    frames = _decode(out)
    centroids = []
    for frame, t in ((frames[0], 0.0), (frames[-1], 5.0)):
        mask = _robot_mask(res.run_dir, frame, t, "top", (320, 240))
        assert mask.mean() > 0.005
        ys, xs = np.nonzero(mask)
        centroids.append(np.array([xs.mean(), ys.mean()]))
    moved_px = np.linalg.norm(centroids[1] - centroids[0])
    moved_m = np.linalg.norm(res.log["q.x"][-1] - res.log["q.x"][0])
    assert moved_m > 0.1 and moved_px > 10.0


def test_keyframe_strip(stand_run, tmp_path):
    from PIL import Image

    out = keyframe_strip(stand_run, tmp_path / "k.png", frames=3, size="80x100")
    assert Image.open(out).size == (240, 100)


def test_two_render_processes_give_the_frames_of_one(stand_run):
    """Frames rendered by 2 worker processes (interleaved, each its own model copy and OpenGL context) arrive in
    order and equal those rendered in this process, overlays and caption included."""
    replay = _render_replay(stand_run)
    plan = _plan(replay, np.linspace(0.0, 1.0, 7), "follow")
    frames = {}
    for workers in (1, 2):
        f = _Frames(replay, plan, (160, 120), "follow", Overlays(), workers)
        try:
            frames[workers] = [img.copy() for img in f]
        finally:
            f.close()
    assert len(frames[1]) == len(frames[2]) == 7
    for a, b in zip(frames[1], frames[2], strict=True):
        assert np.abs(a.astype(int) - b.astype(int)).max() <= 2
    assert np.abs(frames[1][0].astype(int) - frames[1][-1].astype(int)).max() > 0  # the caption's time changed


def test_bgr_frames_and_the_encoding_thread_give_the_same_video(stand_run, tmp_path, monkeypatch):
    """Frames read as BGR into a reused buffer are the RGB frames with the channels swapped, pixel for pixel; a
    video encoded in a thread while the next frames are drawn decodes to the frames of one encoded in turn; a
    drawing error in the middle of a threaded video is raised, not lost in the thread."""
    replay = _render_replay(stand_run)
    r = _Renderer(replay, 160, 120, "follow", Overlays())
    buf = np.zeros((120, 160, 3), np.uint8)
    plan = _plan(replay, np.array([0.0, 0.7]), "follow")
    for i in range(2):
        rgb = r.draw(int(plan.ticks[i]), plan.qpos[i], plan.lookat[i]).copy()
        bgr = r.draw(int(plan.ticks[i]), plan.qpos[i], plan.lookat[i], out=buf, bgr=True)
        assert np.shares_memory(bgr, buf) and rgb.std() > 10
        assert np.array_equal(bgr[..., ::-1], rgb)
    r.close()
    videos = [_decode(render_run(stand_run, tmp_path / f"{threaded}.mp4", size="160x120", fps=15, threaded=threaded))
              for threaded in (True, False)]
    assert len(videos[0]) == len(videos[1]) == 16
    for a, b in zip(*videos, strict=True):
        assert np.array_equal(a, b)
    draw = _Renderer.draw

    def failing(self, k, *args, **kwargs):
        if k > replay.tick_at(0.5):
            raise RuntimeError("frame failed")
        return draw(self, k, *args, **kwargs)

    monkeypatch.setattr(_Renderer, "draw", failing)
    with pytest.raises(RuntimeError, match="frame failed"):
        render_run(stand_run, tmp_path / "fail.mp4", size="160x120", fps=15)


def test_simplified_meshes_keep_the_robot_s_outline(stand_run):
    """The visual meshes drawn from their vertex clustering (about half the faces) give the image of the full
    meshes but for a thin border: few of the robot's pixels change."""
    images, faces = [], []
    for cell in (0.0, 0.015):
        replay = _render_replay(stand_run, mesh_cell=cell)
        faces.append(int(replay.model.mesh_facenum.sum()))
        r = _Renderer(replay, 320, 400, "side", Overlays.none())
        r.camera.distance = 2.2
        images.append(r.frame(0.5).astype(int))
        if cell == 0.0:
            r.options.geomgroup[VISUAL_GROUP] = 0
            robot = np.abs(images[0] - r.frame(0.5)).max(axis=2) > 40
        r.close()
    assert faces[1] < 0.6 * faces[0]
    assert robot.mean() > 0.08
    changed = np.abs(images[0] - images[1]).max(axis=2) > 40
    assert changed.sum() < 0.06 * robot.sum()


def test_visual_meshes_leave_the_run_bit_identical(tmp_path):
    a = run("stand", "tsid-torque", duration=0.3, out=tmp_path / "a")
    b = run("stand", "tsid-torque", duration=0.3, out=tmp_path / "b", sim_options=SimOptions(visuals=True))
    assert a.log.keys() == b.log.keys()
    for k in a.log:
        if k != "controller_time_us":
            np.testing.assert_array_equal(a.log[k], b.log[k], err_msg=k)


def _cli(*args, env=None):
    import os

    return subprocess.run([sys.executable, "-m", "wbcbench.cli", "render", *args], capture_output=True, text=True,
                          env={**os.environ, **(env or {})})


def test_bad_input_is_one_line(stand_run, tmp_path):
    empty, corrupt = bad_run_dirs(tmp_path, stand_run)
    cases = [((str(empty),), {}, "no log.parquet"), ((str(corrupt),), {}, "cannot read the log"),
             ((str(stand_run), "--size", "100x"), {}, "--size"),
             ((str(stand_run), "--camera", "drone"), {}, "drone"),
             ((str(stand_run), "--workers", "0"), {}, "--workers"),
             ((str(stand_run), "--out", str(tmp_path / "x.mp4")), {"MUJOCO_GL": "glx"}, "MUJOCO_GL")]
    for args, env, needle in cases:
        proc = _cli(*args, env=env)
        assert proc.returncode == 2, (args, proc.stderr)
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and needle in lines[0], (args, proc.stderr)
