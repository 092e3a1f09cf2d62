"""One control tick as named phases, and the hooks that take part in them.

A run (`wbcbench.runner.run`) is a `RunLoop`. Before the first tick the hooks of the ``sense`` phase run once on
the simulator's first measurement (with ``tick.k == -1``: the measurement at t = 0) and the controller is reset.
Then every tick k (t = k dt) runs the phases of `PHASES` in this order:

    start      the tick begins: wall-clock pacing, a branch point
    observe    the scenario observes ``tick.meas`` (scenarios that re-plan: step adjustment, teleop safety filter)
    reference  ``tick.refs = scenario.references(t)``; probes' ``observe(t, refs)`` (the live view)
    control    ``tick.cmd = controller.step(tick.meas, tick.refs)``, timed
    safety     a safe stop may replace ``tick.cmd`` (faults' measurement guard, fall prediction)
    actuate    ``plant.apply(tick.cmd)``
    step       ``plant.step(substeps)``: the physics advances one control period
    sense      the state after the step: its ground truth into the log row (``tick.truth``, ``tick.fall``), then
               through the sensor model and the faults into ``tick.meas``, the measurement at t + dt that the next
               tick's controller sees
    record     the log row's other channels: references, the controller's and the scenario's values, probes
    check      the row is committed (``tick.row`` is the next one after it); a fall ends the run; progress

Each phase does the loop's own work first, then calls the hooks registered on it in the order they were
registered. A hook is a `Hook` (its methods named after phases, or its `phases()`), or a ``(phase, callable)``
pair; each is called as ``fn(tick)`` with the `Tick`, whose fields it may read and replace. Before the first tick
the loop makes one flat list of the bound callables of every phase: a tick costs one call per registered callable
and nothing else. A hook ends the run by raising `EndRun` (e.g. from ``check``). The loop calls the simulator only
through the `Plant` interface (apply, step, read_tick, measurement, measure): a model of the actuators or another
physics engine plugs in at ``actuate`` and ``step`` by being the plant or a hook there.
"""

from __future__ import annotations

import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from time import perf_counter
from typing import TYPE_CHECKING, Protocol

import numpy as np

from .errors import ConfigError, WbcError
from .side import Side

if TYPE_CHECKING:
    from .recorder import Recorder
    from .types import Command, Measurement

__all__ = ["PHASES", "Tick", "Hook", "EndRun", "HookError", "Plant", "RunLoop", "LogLayout", "LogWriteError"]

#: the phases of a tick, in the order they run (module docstring)
PHASES = ("start", "observe", "reference", "control", "safety", "actuate", "step", "sense", "record", "check")


class Tick:
    """What one tick's phases hand each other. ``k`` the tick's index and ``t = k dt`` its time [s] (the whole
    tick); ``meas`` the controller's measurement (from the last ``sense``); ``refs`` the scenario's references
    (from ``reference``); ``cmd`` the command (from ``control``, maybe replaced in ``safety``); ``row`` the log row
    being filled (float64, written with the slices of `Recorder.add_channel`); ``truth`` the ground-truth
    measurement after the step and ``fall`` the simulator's fall status (from ``sense``). In the ``sense`` phase
    before the first tick (``k == -1``) only ``meas`` and ``truth`` are set (no row yet)."""

    __slots__ = ("k", "t", "meas", "refs", "cmd", "row", "truth", "fall")

    def __init__(self):
        self.k, self.t = 0, 0.0
        self.meas = self.refs = self.cmd = self.row = self.truth = self.fall = None


class Hook:
    """Something that takes part in the run loop. Define methods named after the phases you need (each called as
    ``method(tick)`` every tick), or override `phases()` to choose them when the loop is built. `attach`, `begin`
    and `end` are called once each (all optional):

        class Track(Hook):
            def attach(self, loop):
                self.slot = loop.recorder.add_channel("my_value")   # a log channel of its own
            def control(self, tick):
                tick.row[self.slot] = tick.cmd.tau[0]              # the command, once the controller made it

        run("stand", "tsid-torque", hooks=[Track()])
    """

    def phases(self) -> dict[str, Callable[[Tick], None]]:
        """phase -> callable(tick): by default the methods named after a phase."""
        return {p: fn for p in PHASES if callable(fn := getattr(self, p, None))}

    def attach(self, loop: RunLoop) -> None:
        """When the loop is built, before its first row: add log channels (``loop.recorder.add_channel``)."""

    def begin(self, loop: RunLoop) -> None:
        """Before the first measurement (``loop.n_ticks`` known); may raise a `ConfigError`."""

    def end(self, loop: RunLoop) -> None:
        """After the last tick, whatever ended the run (called when `begin` was, even after an error)."""


class EndRun(Exception):
    """Raised by a hook to end the run there: ``fell`` says whether the robot is down (``reason`` why). The log
    keeps the rows committed before."""

    def __init__(self, reason: str = "", fell: bool = False):
        super().__init__(reason)
        self.reason, self.fell = reason, fell


class HookError(Exception):
    """A hook's own error, carried past the loop's handler of controller crashes and raised as it is (e.g. a branch
    plan's bug): ``raise HookError(exc)``."""

    def __init__(self, error: BaseException):
        super().__init__(str(error))
        self.error = error


class LogWriteError(WbcError):
    """The run directory could not be written (disk full, removed, no permission) during a run."""


class Plant(Protocol):
    """The simulator as the loop sees it (`wbcbench.sim.simulator.Simulator` is one)."""

    def apply(self, command: Command) -> None: ...

    def step(self, n: int = 1) -> None: ...

    def read_tick(self, row: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, object]: ...

    def measurement(self, state: np.ndarray) -> Measurement: ...

    def measure(self) -> Measurement: ...


@dataclass
class LoopOutcome:
    """How the loop ended: the last tick reached (``k``), a fall or crash (``fell``, ``reason``, ``error`` the
    traceback of a crash), a Ctrl-C, and the wall time from the first measurement [s]."""

    k: int = 0
    fell: bool = False
    reason: str = ""
    error: str | None = None
    interrupted: bool = False
    wall: float = 0.0


class LogLayout:
    """The log's channels that the loop itself writes, registered in this order (the log's column order):
    t, q, v, tau, com, com_vel, com_ref, zmp_ref, foot_ref_*, contact_*, ft_*, in_contact_ref_*, target_*,
    controller_time_us, the controller's channels, the scenario's. Hooks' channels follow (`Hook.attach`)."""

    def __init__(self, rec: Recorder, robot, scenario, controller):
        qlab = ["x", "y", "z", "qx", "qy", "qz", "qw"] + robot.joint_names
        vlab = ["vx", "vy", "vz", "wx", "wy", "wz"] + robot.joint_names
        add = rec.add_channel
        self.t, self.q, self.v = add("t"), add("q", qlab), add("v", vlab)
        self.tau = add("tau", robot.joint_names)
        self.com, self.com_vel = add("com", ["x", "y", "z"]), add("com_vel", ["x", "y", "z"])
        self.com_ref, self.zmp_ref = add("com_ref", ["x", "y", "z"]), add("zmp_ref", ["x", "y", "z"])
        self.foot_ref = {s: add(f"foot_ref_{s.value}", ["x", "y", "z"]) for s in Side}
        wl = ["fx", "fy", "fz", "mx", "my", "mz"]
        cw = {s: add(f"contact_{s.value}", wl) for s in Side}
        ft = {s: add(f"ft_{s.value}", wl) for s in Side}
        flags = {s: add(f"in_contact_ref_{s.value}") for s in Side}
        # each pair of per-side channels is registered left then right, next to each other: written in one go
        cw_all, ft_all, self.in_contact = (slice(d[Side.LEFT].start, d[Side.RIGHT].stop) for d in (cw, ft, flags))
        # where Plant.read_tick writes the ground truth: q, v, tau, both soles' wrenches, both F/T readings
        self.truth_dst = np.array([self.q.start, self.v.start, self.tau.start, cw_all.start, ft_all.start],
                                  dtype=np.int64)
        # the frame-task targets handed to the controller (e.g. teleoperation hands and head): position, rotation
        comps = ["x", "y", "z"] + [f"r{i}{j}" for i in range(3) for j in range(3)]
        self.targets = {name: add(f"target_{name}", comps) for name in scenario.target_names}
        self.controller_time = add("controller_time_us")
        self.controller = [add(name, c) for name, c in controller.log_channels().items()]
        # a scenario may log its own per-tick channels (e.g. the teleoperation command filter's interventions)
        scen_channels = scenario.log_channels() if hasattr(scenario, "log_channels") else {}
        self.scenario = [add(name, c) for name, c in scen_channels.items()]


class RunLoop:
    """The ticks of one run (module docstring). Built with the run's parts, then `add` hooks, then `execute`.

    ``com``: a callable(q, v) -> (com, com velocity) for the ground-truth CoM per tick, or None when the log's
    writer fills those columns per row group."""

    def __init__(self, *, plant: Plant, controller, scenario, recorder: Recorder, layout: LogLayout, dt: float,
                 substeps: int, run_dir: Path, progress: Callable[[float], None] | None = None,
                 com: Callable | None = None):
        self.plant, self.controller, self.scenario = plant, controller, scenario
        self.recorder, self.layout = recorder, layout
        self.dt, self.substeps, self.run_dir = dt, substeps, Path(run_dir)
        self.progress, self.com = progress, com
        self.n_ticks, self.duration = 0, 0.0
        self.ctrl_us = np.zeros(0)
        self.wall0 = 0.0
        self.hooks: list[Hook] = []
        self._extra: dict[str, list] = {p: [] for p in PHASES}
        self.tick = Tick()

    # ------------------------------------------------------------------ registration
    def add_hook(self, hook: Hook) -> None:
        """Register a hook on the phases it names; its channels are added now (`Hook.attach`)."""
        if not isinstance(hook, Hook):
            if not (isinstance(hook, tuple) and len(hook) == 2):
                raise ConfigError(f"a hook is a wbcbench.loop.Hook or a (phase, callable) pair, not "
                                  f"{type(hook).__name__}", key="hooks")
            self.add(*hook)
            return
        hook.attach(self)
        self.hooks.append(hook)
        for phase, fn in hook.phases().items():
            self.add(phase, fn)

    def add(self, phase: str, fn: Callable[[Tick], None]) -> None:
        """Call ``fn(tick)`` every tick in `phase`, after the loop's own work and the hooks registered before."""
        if phase not in PHASES:
            raise ConfigError(f"unknown phase '{phase}'; allowed: {', '.join(PHASES)}", key="hooks")
        if not callable(fn):
            raise ConfigError(f"the hook of phase '{phase}' is not callable ({type(fn).__name__})", key="hooks")
        self._extra[phase].append(fn)

    def calls(self) -> list[Callable[[Tick], None]]:
        """The flat list of a tick's callables, in phase order: the loop's own, then the hooks'."""
        core = self._core()
        out = []
        for phase in PHASES:
            if phase in core:
                out.append(core[phase])
            out += self._extra[phase]
        return out

    # ------------------------------------------------------------------ the loop's own work
    def _core(self) -> dict[str, Callable[[Tick], None]]:
        core = {**self._core_control(), "sense": self._core_sense(), "record": self._core_record(),
                "check": self._core_check()}
        return core

    def _core_control(self) -> dict[str, Callable[[Tick], None]]:
        references, ctrl_step, ctrl_us = self.scenario.references, self.controller.step, self.ctrl_us
        apply, physics, substeps = self.plant.apply, self.plant.step, self.substeps

        def reference(s: Tick) -> None:
            s.refs = references(s.t)

        def control(s: Tick) -> None:
            c0 = perf_counter()
            s.cmd = ctrl_step(s.meas, s.refs)
            ctrl_us[s.k] = (perf_counter() - c0) * 1e6

        def actuate(s: Tick) -> None:
            apply(s.cmd)

        def step(s: Tick) -> None:
            physics(substeps)

        out = {"reference": reference, "control": control, "actuate": actuate, "step": step}
        observe = getattr(self.scenario, "observe", None)
        if observe is not None:  # a scenario that re-plans from the measurement (e.g. step adjustment)
            def observe_phase(s: Tick) -> None:
                observe(s.t, s.meas)

            out["observe"] = observe_phase
        return out

    def _core_sense(self) -> Callable[[Tick], None]:
        read_tick, measurement, dst, com = self.plant.read_tick, self.plant.measurement, self.layout.truth_dst, self.com
        if com is None:
            def sense(s: Tick) -> None:
                # the next tick's measurement, recorded with the state it belongs to: q, v, applied torque, contact
                # wrenches and F/T readings go into the row in the same call
                state, s.fall = read_tick(s.row, dst)
                s.meas = s.truth = measurement(state)  # ground truth before the sensor layer
            return sense
        s_com, s_vcom = self.layout.com, self.layout.com_vel

        def sense_with_com(s: Tick) -> None:  # the CoM per tick (joint types the compiled kernel lacks)
            state, s.fall = read_tick(s.row, dst)
            truth = s.meas = s.truth = measurement(state)
            s.row[s_com], s.row[s_vcom] = com(truth.q, truth.v)
        return sense_with_com

    def _core_record(self) -> Callable[[Tick], None]:
        L = self.layout
        s_ref, s_zmp, s_fref, s_targets, s_in = L.com_ref, L.zmp_ref, L.foot_ref, L.targets, L.in_contact
        s_extra, s_scen, log_values = L.controller, L.scenario, self.controller.log_values
        scen_values = self.scenario.log_values if s_scen else None
        in_contact = _ContactFlags()

        def record(s: Tick) -> None:
            row, refs = s.row, s.refs
            if refs.com is not None:
                row[s_ref] = refs.com.position
            if refs.zmp is not None:
                row[s_zmp] = refs.zmp
            if refs.feet:
                for side, foot in refs.feet.items():
                    row[s_fref[side]] = foot.position
            if s_targets:
                for name, sl in s_targets.items():
                    target = refs.targets.get(name)
                    if target is not None:
                        cells = row[sl]
                        cells[:3] = target.position
                        if target.rotation is not None:
                            cells[3:] = target.rotation.reshape(-1)
            row[s_in] = in_contact[refs.contacts]
            for sl, val in zip(s_extra, log_values()):
                row[sl] = val
            if s_scen:
                for sl, val in zip(s_scen, scen_values()):
                    row[sl] = val
        return record

    def _core_check(self) -> Callable[[Tick], None]:
        commit, dt, loop = self.recorder.commit, self.dt, self

        def check(s: Tick) -> None:
            try:
                s.row = commit()  # the next tick's row
            except OSError as exc:  # e.g. the disk is full: what was flushed stays readable
                raise LogWriteError(f"cannot write the log {loop.run_dir / 'log.parquet'} at t = "
                                    f"{(s.k + 1) * dt:.3f} s ({exc.strerror or exc}); the ticks written "
                                    "before are kept") from None
            if s.fall.fell:
                raise EndRun(s.fall.reason, fell=True)
        return check

    def _progress_hook(self) -> Callable[[Tick], None]:
        progress, n = self.progress, self.n_ticks

        def report(s: Tick) -> None:
            if s.k % 100 == 0:
                progress((s.k + 1) / n)
        return report

    # ------------------------------------------------------------------ running
    def prepare(self, n_ticks: int, duration: float) -> None:
        """The run's length is known (after the scenario's set-up): its per-tick arrays and the time columns."""
        self.n_ticks, self.duration = n_ticks, duration
        self.ctrl_us = ctrl_us = np.full(n_ticks, np.nan)
        i_t, i_time, dt = self.layout.t.start, self.layout.controller_time.start, self.dt

        def time_columns(block: np.ndarray, first: int) -> None:
            """Row k is tick k: its time (the state's, after the step) and the controller's step time, filled per
            row group (the same numbers as per tick)."""
            ticks = np.arange(first + 1, first + 1 + len(block))
            block[:, i_t] = ticks * dt
            block[:, i_time] = ctrl_us[first:first + len(block)]

        self.recorder.derive(time_columns)
        if self.progress is not None:
            self.add("check", self._progress_hook())

    def execute(self, reset: Callable[[object], None]) -> LoopOutcome:
        """Run the ticks: the hooks begin, the first measurement is sensed and ``reset(meas)`` called (the
        controller's reset), then the ticks until the end, a fall, a crash or a Ctrl-C (`LoopOutcome`). A
        `WbcError` or a `HookError`'s error is raised as it is; the log is closed in every case."""
        out, s, begun = LoopOutcome(), self.tick, []
        try:
            for hook in self.hooks:
                hook.begin(self)
                begun.append(hook)
            self.wall0 = perf_counter()
            self._first_measurement(s, reset)
            self._ticks(s, self.calls())
        except EndRun as exc:
            out.fell, out.reason = exc.fell, exc.reason
        except WbcError:
            _close_quietly(self.recorder)
            raise
        except HookError as exc:
            _close_quietly(self.recorder)
            raise exc.error from None
        except KeyboardInterrupt:  # Ctrl-C: stop here, keep the log and say so in the summary
            out.interrupted = True
        except Exception as exc:  # a crash in a controller: keep the log, say why
            if _from_interrupt(exc):  # Ctrl-C inside a compiled call, which re-raised it as another error
                out.interrupted = True
            else:
                out.fell, out.reason = True, f"error: {type(exc).__name__}: {exc}"
                out.error = traceback.format_exc()
        finally:
            _close_quietly(self.recorder)
            for hook in reversed(begun):
                hook.end(self)
        out.k = max(s.k, 0)
        out.wall = perf_counter() - self.wall0
        return out

    def _first_measurement(self, s: Tick, reset: Callable[[object], None]) -> None:
        """The sense phase's hooks on the simulator's first measurement (tick -1's sense: t = 0), then the reset."""
        s.k = -1
        s.meas = s.truth = self.plant.measure()
        for fn in self._extra["sense"]:
            fn(s)
        s.k = 0
        reset(s.meas)
        s.row = self.recorder.row  # the row of this tick's log (the recorder hands out the next one at each commit)

    def _ticks(self, s: Tick, calls: Iterable[Callable[[Tick], None]]) -> None:
        dt, calls = self.dt, tuple(calls)
        for k in range(self.n_ticks):
            s.k = k
            s.t = k * dt
            for fn in calls:
                fn(s)


def _from_interrupt(exc: BaseException) -> bool:
    """Whether an error was caused by a Ctrl-C: a KeyboardInterrupt raised while a compiled kernel was calling back
    into the interpreter comes out of the kernel as a SystemError whose cause is the interrupt."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


class _ContactFlags(dict):
    """contacts (a frozenset of sides) -> the row's (in_contact_ref_left, in_contact_ref_right), made once."""

    def __missing__(self, contacts):
        flags = self[contacts] = np.array([float(s in contacts) for s in Side])
        return flags


def _close_quietly(rec: Recorder) -> None:
    try:
        rec.close()
    except OSError:  # the log cannot be completed (disk full): what was flushed stays readable
        pass
