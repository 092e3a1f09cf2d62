"""The run loop's built-in hooks (`wbcbench.loop`): probes, the sensor model, faults, fall prediction and its safe
stop, and wall-clock pacing. Each registers on the phases it needs and adds its own log channels; `runner.run`
registers those a run asks for, in this order (the log's column order): probes, sensors, faults, fall
prediction, pacing."""

from __future__ import annotations

import gc
import os
import sys
import time
from collections.abc import Callable, Sequence

import numpy as np

from .estimation.fall import FallPredictor
from .faults import FaultInjector
from .loop import Hook, RunLoop, Tick

__all__ = ["ProbeHook", "SensorHook", "FaultHook", "FallHook", "PacingHook"]


class ProbeHook(Hook):
    """Probes (`runner.run(probes=...)`): each has ``attach(sim) -> {channel: components}`` (its log channels),
    ``values()`` (after every tick: ``record``) and maybe ``observe(t, refs)`` (the references handed to the
    controller: ``reference``, e.g. the live view)."""

    def __init__(self, probes: Sequence):
        self.probes = tuple(probes)

    def attach(self, loop: RunLoop) -> None:
        add = loop.recorder.add_channel
        self.slots = [[add(name, comps) for name, comps in p.attach(loop.plant).items()] for p in self.probes]

    def phases(self) -> dict[str, Callable[[Tick], None]]:
        out = {"record": self.record} if self.probes else {}
        observers = [p.observe for p in self.probes if hasattr(p, "observe")]
        if observers:
            def observe(s: Tick) -> None:
                for obs in observers:
                    obs(s.t, s.refs)

            out["reference"] = observe
        return out

    def record(self, s: Tick) -> None:
        row = s.row
        for slices, p in zip(self.slots, self.probes):
            for sl, val in zip(slices, p.values()):
                row[sl] = val


class SensorHook(Hook):
    """The sensor model (`wbcbench.sensing`): the true measurement through it (``sense``, unless ideal), and the
    base estimate's error logged (``record``, when it estimates the base)."""

    def __init__(self, sensing):
        self.sensing = sensing

    def attach(self, loop: RunLoop) -> None:
        self.slot = (loop.recorder.add_channel("base_estimate_error", ["x", "y", "z", "rx", "ry", "rz"])
                     if self.sensing.estimator is not None else None)

    def phases(self) -> dict[str, Callable[[Tick], None]]:
        out = {}
        if not self.sensing.ideal:  # else the controller sees the simulator's measurement as it is
            out["sense"] = self.sense
        if self.slot is not None:
            out["record"] = self.record
        return out

    def sense(self, s: Tick) -> None:
        s.meas = self.sensing.measure(s.meas)

    def record(self, s: Tick) -> None:
        s.row[self.slot] = self.sensing.base_error()


class FaultHook(Hook):
    """A fault schedule (`wbcbench.faults.FaultInjector`). ``sense``: the flags of the tick that ends go to the
    log, the faults due at the measurement's time start or end (joint faults on the plant, QP failures through the
    controller's solve hook), sensor faults and the measurement guard act on ``tick.meas``; ``safety``: the guard's
    safe stop replaces the command once it is on."""

    def __init__(self, injector: FaultInjector):
        self.injector = injector

    def attach(self, loop: RunLoop) -> None:
        self.slot = loop.recorder.add_channel("faults", list(self.injector.LOG_LABELS))
        self.dt, self.plant, self.controller = loop.dt, loop.plant, loop.controller

    def sense(self, s: Tick) -> None:
        inj = self.injector
        if s.k >= 0:
            s.row[self.slot] = inj.log
        inj.update((s.k + 1) * self.dt, self.plant, self.controller)
        s.meas = inj.measurement(s.meas)

    def safety(self, s: Tick) -> None:
        s.cmd = self.injector.safe_stop(s.meas, self.controller.mode, s.refs.contacts) or s.cmd


class FallHook(Hook):
    """Fall prediction from the measurement (capture point vs support polygon, tilt rate; ``safety``, logged), and
    with ``safe_stop`` joint-pd about the posture at the first prediction, for good, in place of the controller."""

    def __init__(self, robot, safe_stop: bool):
        self.robot, self.safe_stop = robot, safe_stop
        self.predictor = FallPredictor(robot)
        self.stopper = None

    def attach(self, loop: RunLoop) -> None:
        self.slot = loop.recorder.add_channel("fall_prediction", list(FallPredictor.LOG_LABELS))
        self.dt, self.mode = loop.dt, loop.controller.mode

    def safety(self, s: Tick) -> None:
        predictor = self.predictor
        s.row[self.slot] = predictor.update(s.meas)
        if self.safe_stop and predictor.first_prediction_t is not None:
            if self.stopper is None:  # joint-pd about the posture at the prediction, for good
                from .controllers.joint_pd import JointPD

                self.stopper = JointPD(self.robot, self.mode, self.dt)
                self.stopper.q_ref = s.meas.q[7:].copy()
            s.cmd = self.stopper.step(s.meas, s.refs)


#: [s] a paced run that falls further behind than this resumes from the wall clock (the stall is counted)
#: instead of running the simulation faster than real time to catch up
MAX_CATCH_UP = 0.005

#: the paced loop's real-time priority (SCHED_FIFO, 1-99): low, above every normal thread and below the kernel's own
#: real-time threads; the log's writer thread runs 5 below it
REALTIME_PRIORITY = 10


class PacingHook(Hook):
    """Paced to the wall clock (``start``): tick k starts at the first tick's end + (k - 1) dt, or late; how late
    each tick started [ms] is logged (``lateness_ms``), with the causes apart for the summary: how late each sleep
    returned (the machine) and each tick's own time (the work). For the run the loop's thread asks for the
    real-time class, cyclic garbage collection pauses and the interpreter switches threads sooner (`begin`, `end`)."""

    def attach(self, loop: RunLoop) -> None:
        self.slot = loop.recorder.add_channel("lateness_ms")

    def begin(self, loop: RunLoop) -> None:
        n = loop.n_ticks
        self.lateness, self.overslept, self.busy = np.zeros(n), np.zeros(n), np.full(n, np.nan)
        self.wall_start = self.started = 0.0
        # no cyclic garbage collection during the loop (a full collection stalls the interpreter for milliseconds;
        # the loop's objects are freed by reference counting), what exists now moved out of its reach
        self.gc_paused = gc.isenabled()
        if self.gc_paused:
            gc.collect()
            gc.freeze()
            gc.disable()
        # the interpreter back from the log's writer thread within 0.2 ms instead of Python's 5 ms (the writer
        # builds a row group's Arrow columns in Python while holding it)
        self.switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(min(self.switch_interval, 2e-4))
        # the real-time scheduling class, as a robot's control thread has, where it may: the kernel's and other
        # programs' threads no longer preempt it for milliseconds (it sleeps every tick, so they run then; threads
        # started before, e.g. the log's writer, keep the normal class)
        self.priority = _raise_priority()
        if self.priority is not None and self.priority[1]:
            loop.recorder.set_writer_priority(REALTIME_PRIORITY - 5)

    def end(self, loop: RunLoop) -> None:
        if self.gc_paused:
            gc.enable()
            gc.unfreeze()
        sys.setswitchinterval(self.switch_interval)
        if self.priority is not None:
            _restore_priority(self.priority)

    def start(self, s: Tick) -> None:
        k, t = s.k, s.t
        if k > 0:  # tick k starts at wall_start + k dt, or late
            now = time.perf_counter()
            if k == 1:  # the clock starts after the first tick (one-off start-up work is not a delay)
                self.wall_start = now - t
            else:  # the previous tick's own time, from its start to now
                self.busy[k - 1] = (now - self.started) * 1e3
            late = now - (self.wall_start + t)
            if late < 0:
                time.sleep(-late)
                started = time.perf_counter()
                late = started - (self.wall_start + t)
                if late > 0:  # the sleep returned after the tick's start: the machine's scheduling
                    self.overslept[k] = late * 1e3
            else:
                started = now
            self.started = started
            if late > 0:
                self.lateness[k] = late * 1e3
                if late > MAX_CATCH_UP:  # a stall: resume from now rather than rush to catch up
                    self.wall_start += late
        s.row[self.slot] = self.lateness[k]

    def summary(self, k: int, dt: float, sim_time: float, wall: float) -> dict:
        """The summary's ``realtime`` section, up to tick k."""
        n = k + 1
        return {**lateness_summary(self.lateness[:n], dt, sim_time, wall, self.overslept[:n], self.busy[:n]),
                "scheduling": ("real-time (SCHED_FIFO)" if self.priority and self.priority[1]
                               else "normal (real-time class not permitted)")}


def _raise_priority() -> tuple | None:
    """Put the calling thread in the real-time class (SCHED_FIFO at `REALTIME_PRIORITY`) when the system allows;
    (the previous policy and parameters, whether it was raised), or None where the call does not exist."""
    if not hasattr(os, "sched_setscheduler"):
        return None
    before = (os.sched_getscheduler(0), os.sched_getparam(0))
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(REALTIME_PRIORITY))
    except OSError:  # no CAP_SYS_NICE / RLIMIT_RTPRIO: the normal class
        return before, False
    return before, True


def _restore_priority(priority: tuple) -> None:
    (policy, param), raised = priority
    if raised:
        try:
            os.sched_setscheduler(0, policy, param)
        except OSError:
            pass


def lateness_summary(late_ms: np.ndarray, dt: float, sim_time: float, wall: float, overslept_ms: np.ndarray,
                     busy_ms: np.ndarray) -> dict:
    """A wall-clock-paced run: how many ticks started more than one control period late, the worst lateness
    [ms], and whether it kept up (no tick later than 5 ms); and the two causes of lateness apart: the longest a
    sleep returned after its tick's start (`worst_oversleep_ms`: the machine's scheduling, the loop had nothing to
    do) and the ticks whose own time exceeded the period (`slow_ticks`, the longest `worst_tick_ms`: the work)."""
    worst = float(late_ms.max()) if late_ms.size else 0.0
    timed = busy_ms[np.isfinite(busy_ms)]
    return {"late_ticks": int((late_ms > dt * 1e3).sum()), "worst_lateness_ms": worst,
            "kept_up": worst <= 5.0, "wall_time_s": wall, "sim_time_s": sim_time,
            "worst_oversleep_ms": float(overslept_ms.max()) if overslept_ms.size else 0.0,
            "slow_ticks": int((timed > dt * 1e3).sum()), "worst_tick_ms": float(timed.max()) if timed.size else 0.0}
