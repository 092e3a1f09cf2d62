"""The live view (wbcbench/viz/live.py): a run with it is bit-identical to one without (it only reads the
simulator), it publishes frames at its display rate, and a teleoperation session shows the operator's targets,
live and in the replay."""

import socket

import numpy as np

from wbcbench.runner import run
from wbcbench.viz.live import LiveView


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_run_with_the_live_view_is_bit_identical(tmp_path):
    view = LiveView(port=_free_port(), rate=1e9)  # a frame every tick: the most it could ever disturb
    try:
        b = run("stand", "joint-pd", duration=0.4, out=tmp_path / "b", probes=[view])
        assert view.published == len(b.log["t"]) and view.shown > 0
        body = view.robot.frames[0]
        assert np.isfinite(body.position).all() and body.position[2] > 0.5  # the base, standing
    finally:
        view.close()
    assert not view._thread.is_alive()
    a = run("stand", "joint-pd", duration=0.4, out=tmp_path / "a")
    assert a.log.keys() == b.log.keys()
    for k in a.log:
        if k != "controller_time_us":
            np.testing.assert_array_equal(a.log[k], b.log[k], err_msg=k)


def test_teleop_shows_the_targets(tmp_path):
    from wbcbench.teleop.commands import run_session

    view = LiveView(port=_free_port(), rate=50.0)
    try:
        result = run_session("reach_forward", duration=0.2, out=tmp_path / "t", view=view)
    finally:
        view.close()
    assert set(view._targets) >= {"left_hand", "right_hand", "head"}, set(view._targets)
    right = view._targets["right_hand"].position
    logged = np.array([result.log[f"target_right_hand.{a}"] for a in "xyz"]).T
    assert np.min(np.linalg.norm(logged - right, axis=1)) < 1e-9  # a logged target, at one of the ticks shown


def test_the_replay_shows_the_logged_targets(tmp_path):
    from wbcbench.teleop.commands import run_session
    from wbcbench.viz.viewer import ReplayViewer

    res = run_session("reach_forward", duration=0.2, out=tmp_path / "t")
    with ReplayViewer([res.run_dir], port=_free_port()) as viewer:
        viewer.show(0.1)
        k = viewer.replays[0].tick_at(0.1)
        frame, _ = viewer.marks[0]["targets"]["right_hand"]
        logged = [res.log[f"target_right_hand.{a}"][k] for a in "xyz"]
        np.testing.assert_allclose(frame.position, logged, atol=1e-12)
        assert frame.visible
