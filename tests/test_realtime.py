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
    rt = s["realtime"]  # told apart: the tick's own time, not a late sleep
    assert rt["slow_ticks"] >= 1 and rt["worst_tick_ms"] >= 25.0


def test_a_late_sleep_is_the_ticks_own_lateness_and_told_apart(talos, tmp_path, monkeypatch):
    """A sleep that returns 20 ms after its deadline once (the machine did not run the loop in time): that very
    tick is logged 20 ms late (not the next one), the summary names the sleep's overrun apart from the ticks' own
    time, and its line says the machine's scheduling was the cause."""
    import wbcbench.runner as runner_module
    from wbcbench.summary import pacing_text

    real_sleep = time.sleep
    sleeps = [0]

    def late_sleep(seconds):
        sleeps[0] += 1
        real_sleep(seconds + (0.02 if sleeps[0] == 150 else 0.0))

    monkeypatch.setattr(runner_module.time, "sleep", late_sleep)
    res = run("stand", "joint-pd", duration=0.3, out=tmp_path / "r", realtime=True)
    monkeypatch.undo()
    rt, late = res.summary["realtime"], res.log["lateness_ms"]
    k = 140 + int(np.argmax(late[140:170]))  # the 150th sleep is about the 150th tick's (joint-pd sleeps every tick)
    assert late[k] >= 19.0 and late[k + 1] < 5.0  # the stall's own tick; the schedule resumed from the clock
    assert rt["worst_oversleep_ms"] >= 19.0 and not rt["kept_up"]
    if rt["worst_tick_ms"] <= 5.0:  # the machine running this test may itself stall a tick
        assert "the machine's scheduling" in pacing_text(rt)


def test_a_paced_loop_runs_above_its_log_writer_and_returns_to_normal(talos, tmp_path):
    """Where the system allows the real-time class, a paced loop runs in it with the log's writer thread below
    it (a writer at the loop's own priority ran whole row groups, 30-60 ms, before the loop got the core back),
    and the thread is back in its normal class after the run; where it does not, the summary says so."""
    import os
    import threading

    import pytest

    if not hasattr(os, "sched_getscheduler"):
        pytest.skip("no POSIX scheduling here")
    seen = {}

    class Probe:  # reads the loop's and the writer's scheduling during the run
        def attach(self, sim):
            return {}

        def values(self):
            if not seen:
                seen["loop"] = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
                writer = next(t for t in threading.enumerate() if t.name == "wbcbench-log-writer")
                seen["writer"] = os.sched_getscheduler(writer.native_id), os.sched_getparam(writer.native_id).sched_priority
            return []

        def metrics(self, log):
            return {}

    before = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    res = run("stand", "joint-pd", duration=0.05, out=tmp_path / "r", realtime=True, probes=[Probe()])
    assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == before
    if res.summary["realtime"]["scheduling"].startswith("normal"):
        assert seen["loop"] == before
        return
    (loop_policy, loop_prio), (writer_policy, writer_prio) = seen["loop"], seen["writer"]
    assert loop_policy == os.SCHED_FIFO and writer_policy == os.SCHED_FIFO and 0 < writer_prio < loop_prio
