"""The run loop's phases and hooks (wbcbench/loop.py): the phases run in the documented order, a hook registered on
a phase is called every tick with what that phase promises, a hook can end the run or replace the command, and a
controller's QP solves go through its solve hook."""

from __future__ import annotations

import numpy as np
import pytest

from wbcbench.controllers.base import make_controller
from wbcbench.errors import ConfigError
from wbcbench.faults import Fault
from wbcbench.loop import PHASES, EndRun, Hook
from wbcbench.runner import run


class _Order(Hook):
    """Records (phase, tick index) for every phase."""

    def __init__(self):
        self.seen = []

    def phases(self):
        return {p: (lambda s, p=p: self.seen.append((p, s.k))) for p in PHASES}


def test_phases_run_in_the_documented_order(talos, tmp_path):
    hook = _Order()
    res = run("stand", "joint-pd", talos, duration=0.01, out=tmp_path / "r", hooks=[hook])
    n = len(res.log["t"])
    assert n == 10 and PHASES == ("start", "observe", "reference", "control", "safety", "actuate", "step", "sense",
                                  "record", "check")
    # the sense phase once before the first tick (the measurement at t = 0), then every phase of every tick in order
    assert hook.seen == [("sense", -1)] + [(p, k) for k in range(n) for p in PHASES]


class _Commands(Hook):
    """A user's hook: the command once the controller made it, the measurement after the step, and a log channel
    of its own written in the record phase."""

    def __init__(self, joint: int):
        self.joint, self.t, self.tau, self.meas_t = joint, [], [], []

    def attach(self, loop):
        self.slot = loop.recorder.add_channel("my_tau")

    def control(self, tick):
        self.t.append(tick.t)
        self.tau.append(float(tick.cmd.tau[self.joint]))

    def sense(self, tick):
        self.meas_t.append(tick.meas.t)

    def record(self, tick):
        tick.row[self.slot] = tick.cmd.tau[self.joint]


def test_a_hook_sees_each_ticks_time_and_command(talos, tmp_path):
    joint = talos.joint_names.index("leg_left_4_joint")  # the knee: a large, well-defined holding torque
    hook = _Commands(joint)
    res = run("stand", "joint-pd", talos, duration=0.05, out=tmp_path / "r", hooks=[hook])
    log, n = res.log, 50
    assert len(log["t"]) == n
    np.testing.assert_array_equal(hook.t, np.arange(n) * 1e-3)
    # the command the hook saw is the one the simulator applied (torque mode: the actuator's torque) and logged
    np.testing.assert_array_equal(log["my_tau"], hook.tau)
    np.testing.assert_allclose(log["tau.leg_left_4_joint"], hook.tau, rtol=1e-12, atol=1e-12)
    assert np.abs(hook.tau).min() > 1.0
    # sense hands on the measurement at t + dt (first at t = 0, before the first tick)
    np.testing.assert_allclose(hook.meas_t, np.arange(n + 1) * 1e-3, atol=1e-12)
    # the user's channel comes after every built-in one: the built-in layout is unchanged
    assert list(log)[-1] == "my_tau"


def test_a_safety_hook_replaces_the_command_and_a_hook_ends_the_run(talos, tmp_path):
    from wbcbench.types import Command

    def limp(tick):  # a user's safety filter: no torque at all
        tick.cmd = Command(tau=np.zeros(talos.na))

    def stop_after_20(tick):
        if tick.k == 19:
            raise EndRun("enough")

    res = run("stand", "joint-pd", talos, duration=0.1, out=tmp_path / "r",
              hooks=[("safety", limp), ("check", stop_after_20)])
    s, log = res.summary, res.log
    assert len(log["t"]) == 20 and s["sim_time_s"] == pytest.approx(0.02) and not s["fell"]
    assert np.abs(log["tau.leg_left_4_joint"]).max() == 0.0
    with pytest.raises(ConfigError, match="unknown phase 'control_step'; allowed: start, observe"):
        run("stand", "joint-pd", talos, duration=0.01, out=tmp_path / "bad", hooks=[("control_step", limp)])


def test_the_solve_hook_sees_every_qp_solve(talos, tmp_path):
    """A counting solve hook on tsid-torque changes nothing in the log and sees at least one solve per tick; a
    qp_failure fault goes through the same hook and leaves the controller's solvers as they were."""
    ctrl = make_controller("tsid-torque", talos, None, 1e-3)
    calls = []

    def count(solver, args):
        calls.append(solver)
        return solver.solve(*args)

    ctrl.set_solve_hook(count)
    hooked = run("stand", ctrl, talos, duration=0.05, out=tmp_path / "hooked").log
    plain = run("stand", "tsid-torque", talos, duration=0.05, out=tmp_path / "plain").log
    assert len(calls) >= 50 and calls[0] is ctrl.solver
    for col in plain:
        if col != "controller_time_us":
            np.testing.assert_array_equal(hooked[col], plain[col], err_msg=col)
    faulty = make_controller("tsid-torque", talos, None, 1e-3)
    res = run("stand", faulty, talos, duration=0.1, out=tmp_path / "fault", faults=[Fault("qp_failure", 0.02, 0.01)])
    assert res.summary["controller_status"]["qp_fallback_ticks"] == 10
    assert faulty.solve_hook is not None
    assert not any("solve" in vars(getattr(faulty, name)) for name in ("solver", "relaxed_solver", "torque_solver"))
