"""The browser replay (wbcbench/viz/viewer.py) from the server's side: the robot's body frames and the overlay
markers sent for a time are the logged ones, the plots' cursor follows the timeline, several runs share it, and
bad input (no log, a damaged log, a port in use) is one line with exit code 2."""

import socket
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from wbcbench.viz.viewer import SIDE_SPACING, ReplayViewer

from .conftest import bad_run_dirs


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def viewer(walk_run):
    v = ReplayViewer([walk_run, walk_run], port=_free_port())
    yield v
    v.close()


def test_frames_follow_the_log(viewer):
    rp, robot, marks = viewer.replays[0], viewer.robots[0], viewer.marks[0]
    base = int(np.nonzero(robot.bodies == mujoco.mj_name2id(rp.model, mujoco.mjtObj.mjOBJ_BODY,
                                                            rp.model.body(1).name))[0][0])
    seen = []
    for t in (0.0, viewer.duration):
        viewer.show(t)
        k = rp.tick_at(t)
        np.testing.assert_allclose(robot.frames[base].position, rp.q[k, :3], atol=1e-9)  # the free base
        np.testing.assert_allclose(marks["com"].position[:2], rp.channels["com"][k, :2], atol=1e-9)
        seen.append(robot.world_pos.copy())
    moved = np.linalg.norm(seen[1] - seen[0], axis=1)
    assert moved.max() > 0.03  # the stepping foot has moved between the start and 3 s
    # the right foot carries no weight at 3 s: no force arrow there, the left one points up with the weight
    assert not marks["force_right"].visible and marks["force_left"].visible
    f = marks["force_left"].points[0]
    assert f[1, 2] - f[0, 2] > 0.5  # > 500 N, 1 m per 1000 N


def test_plot_cursor_follows_the_timeline(viewer):
    viewer.show(1.234)
    viewer._update_plots(viewer.time)
    x, *series = viewer.plots[0]["handle"].data
    now = series[-1]
    cursor = np.isfinite(now)
    assert cursor.sum() == 2 and np.allclose(x[cursor], 1.234)
    assert now[cursor][0] < now[cursor][1]  # from the bottom of the plot to its top
    assert np.all(np.diff(x) >= 0)
    assert len(series) - 1 == 4  # CoM y and its reference, for each of the two runs
    assert viewer.slider.value == 1.234
    viewer.plots[0]["menu"].value = "log: q.z"  # any log column, chosen in the page
    x, *series = viewer.plots[0]["handle"].data
    assert len(series) == 3 and np.isclose(series[0][0], viewer.replays[0].q[0, 2])
    viewer.plots[0]["menu"].value = "CoM y and reference [m]"


def test_layouts(viewer):
    viewer.set_layout("side")
    ys = [r.position[1] for r in viewer.roots]
    assert abs(abs(ys[1] - ys[0]) - SIDE_SPACING) < 1e-9
    assert viewer.robots[1].meshes[0].opacity is None
    viewer.set_layout("ghost")
    assert [r.position[1] for r in viewer.roots] == [0.0, 0.0]
    assert viewer.robots[1].meshes[0].opacity < 1 and viewer.robots[0].meshes[0].opacity is None


def test_bad_input_is_one_line(walk_run, tmp_path):
    """No log, a damaged log, a port in use: `wbcbench view` says so in one line, exit code 2 (the three run at
    once: the command line's start-up is most of their time)."""
    empty, corrupt = bad_run_dirs(tmp_path, walk_run)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = str(busy.getsockname()[1])
        cases = [((str(empty),), "no log.parquet"), ((str(corrupt),), "cannot read the log"),
                 ((str(walk_run), "--port", port), f"option --port: cannot serve on 127.0.0.1:{port}")]
        procs = [subprocess.Popen([sys.executable, "-m", "wbcbench.cli", "view", *args], stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True) for args, _ in cases]
        try:
            for proc, (args, needle) in zip(procs, cases):
                _, err = proc.communicate(timeout=180)
                assert proc.returncode == 2, (args, err)
                lines = err.strip().splitlines()
                assert len(lines) == 1 and needle in lines[0], (args, err)
        finally:
            for proc in procs:
                if proc.poll() is None:
                    proc.kill()
                    proc.wait()


def test_bad_options_before_a_port_is_taken(walk_run):
    from wbcbench.errors import ConfigError
    from wbcbench.viz.live import LiveView

    with pytest.raises(ConfigError, match="unknown layout 'stacked'; allowed: ghost, side"):
        ReplayViewer([walk_run], port=_free_port(), layout="stacked")
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        with pytest.raises(ConfigError, match="option --view-port: cannot serve on"):
            LiveView(port=busy.getsockname()[1])
