"""Wall-clock pacing (`run(..., realtime=True)`, `--realtime`): the simulation does not run ahead of the wall
clock, lateness is logged and summarised, and a stall is counted and resumed from, not caught up in a rush."""

import time

import numpy as np

from wbcbench.controllers.joint_pd import JointPD
from wbcbench.runner import run
from wbcbench.types import ActuationMode


def test_a_paced_run_takes_at_least_its_simulated_time(talos, tmp_path):
    res = run("stand", "joint-pd", duration=0.3, out=tmp_path / "r", realtime=True)
    s, log = res.summary, res.log
    assert s["wall_time_s"] >= 0.3 - 2e-3  # the first tick is not paced
    late = log["lateness_ms"]
    assert (late >= 0).all() and s["realtime"]["worst_lateness_ms"] == late.max()
    assert s["realtime"]["late_ticks"] == int((late > 1.0).sum())
    assert run("stand", "joint-pd", duration=0.3, out=tmp_path / "u").summary["realtime"] is None


def test_a_stall_is_counted_and_not_caught_up_in_a_rush(talos, tmp_path):
    """A controller that hangs for 30 ms once: the next tick is >= 25 ms late, the run says it could not keep
    up, and the stall is added to the wall time (the schedule resumes from the clock) instead of the following
    ticks being run back to back."""
    ctrl = JointPD(talos, ActuationMode.TORQUE, 1e-3)
    step = ctrl.step
    calls = [0]

    def slow_step(meas, refs):
        calls[0] += 1
        if calls[0] == 100:
            time.sleep(0.03)
        return step(meas, refs)

    ctrl.step = slow_step
    res = run("stand", ctrl, robot=talos, duration=0.3, out=tmp_path / "s", realtime=True)
    s, late = res.summary, res.log["lateness_ms"]
    assert late[99:102].max() >= 25.0 and not s["realtime"]["kept_up"]
    assert s["wall_time_s"] >= 0.3 + 0.025
    assert np.argmax(late) in (99, 100, 101)
