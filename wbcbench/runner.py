"""The run loop: scenario -> controller -> simulator at the control rate, every tick recorded.

A run directory holds config.json (everything resolved), log.parquet (one row per control tick) and
summary.json. A run that falls or fails still writes its log up to the failure and says why.
"""

from __future__ import annotations

import dataclasses
import gc
import json
import math
import os
import platform
import sys
import time
import traceback
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from .controllers.base import Controller, make_controller
from .metrics.from_log import compute_run_metrics
from .errors import ConfigError, WbcError
from .recorder import Recorder, read_log
from .robots import Robot, Side, load_robot
from .scenarios import Scenario, load_scenario
from .scenarios.base import robot_sizes
from .sim.model import SimOptions
from .estimation.fall import FallPredictor
from .faults import FaultInjector
from .sensing import make_sensor_model
from .stabilizers.base import MissingReferenceError
from .tasks.placements import CenterOfMass
from .sim.engines import make_simulator
from .sim.simulator import Simulator


@dataclass
class RunResult:
    run_dir: Path
    summary: dict
    log: dict[str, np.ndarray] = field(repr=False, default_factory=dict)


def _base_labels(robot: Robot) -> tuple[list[str], list[str]]:
    q = ["x", "y", "z", "qx", "qy", "qz", "qw"] + robot.joint_names
    v = ["vx", "vy", "vz", "wx", "wy", "wz"] + robot.joint_names
    return q, v


def step_time_stats(us: np.ndarray) -> dict:
    us = us[np.isfinite(us)]
    if us.size == 0:
        return {"median": None, "p99": None, "max": None, "mean": None}
    return {"median": float(np.median(us)), "p99": float(np.percentile(us, 99)), "max": float(us.max()),
            "mean": float(us.mean())}


@dataclass(frozen=True)
class Branch:
    """One continuation of a run from its branch point: its own run directory and the pushes it adds."""

    out: Path
    pushes: tuple = ()


@dataclass(frozen=True)
class BranchPoint:
    """Run once up to time `t`, then continue several times from that same state, each continuation (a
    `Branch`) in a child process of its own (`os.fork`: the simulator, controller, sensing and scenario as they
    are, nothing rebuilt or re-simulated) that writes a complete run directory (log from t = 0, config with its
    pushes, summary) exactly as a run with those pushes from the start would (a branch's pushes must not start
    before `t`).

    `plan()` is a generator: it yields the first `Branch`, is sent the summary of each finished branch (a dict
    with "error" when the branch's process died) and yields the next, until it returns. The branches run one
    after another, so the next can depend on the last (e.g. a bisection over a push's force). The run that
    branches ends at `t`: its own directory keeps the log up to there and its summary counts the branches."""

    t: float
    plan: Callable[[], Generator[Branch, dict, None]]


def run(scenario: str | Scenario, controller: str | Controller, robot: str | Robot = "talos",
        mode: str | None = None, duration: float | None = None, out: str | Path | None = None,
        progress: Callable[[float], None] | None = None, sim_options: SimOptions | None = None,
        probes: Sequence = (), taskset: str | Path | None = None, sensors=None, seed: int = 0,
        model_error=None, faults: Sequence = (), predict_falls: bool = False, safe_stop: bool = False,
        overwrite: bool = False, realtime: bool = False, branch: BranchPoint | None = None,
        engine: str = "mujoco") -> RunResult:
    """Run one scenario with one controller; returns the summary (and the log, read back).

    `controller` is a registered name, or a controller already built for this robot at the scenario's
    control_dt (its `mode` is used; `mode` must then be None or the same). `probes` observe the simulator:
    each has `attach(sim) -> {channel: components}` (called once), `values() -> list` (after every tick,
    logged in those channels) and `metrics(log) -> dict` (merged into the summary's metrics); e.g.
    `wbcbench.sim.self_collision.SelfCollisionProbe`. A probe may also have `observe(t, refs)`, called with the
    references handed to the controller every tick (e.g. the live view, `wbcbench.viz.live.LiveView`).
    `branch`: continue the run several times from one state (`BranchPoint`). `engine`: the physics engine
    (`wbcbench.sim.engines`: mujoco, dart or a plugin's).
    """
    global _BRANCH_CHILD
    try:
        result = _run(scenario, controller, robot, mode, duration, out, progress, sim_options, probes, taskset,
                      sensors, seed, model_error, faults, predict_falls, safe_stop, overwrite, realtime, branch,
                      engine)
    except BaseException:
        if _BRANCH_CHILD:  # a branch's process never returns into its parent's code
            _branch_exit(1, traceback.format_exc())
        raise
    if _BRANCH_CHILD:
        _branch_exit(0, None)
    return result


#: True in a branch's child process (see `BranchPoint`)
_BRANCH_CHILD = False


def _branch_exit(code: int, error: str | None) -> None:
    """End a branch's process. An error that escaped the run goes to the branch's error.txt (not to a stream
    whose lock another thread of the parent may have held at the fork); nothing of the parent's runs at exit."""
    try:
        if error and _BRANCH_DIR is not None:
            (_BRANCH_DIR / "error.txt").write_text(error)
    finally:
        os._exit(code)


#: the run directory of this branch's process (see `BranchPoint`)
_BRANCH_DIR: Path | None = None


def _run(scenario, controller, robot, mode, duration, out, progress, sim_options, probes, taskset, sensors, seed,
         model_error, faults, predict_falls, safe_stop, overwrite, realtime, branch, engine="mujoco") -> RunResult:
    robot = load_robot(robot) if isinstance(robot, str) else robot
    scen = load_scenario(scenario, robot, duration) if isinstance(scenario, str) else scenario
    spec = scen.spec
    options = sim_options or SimOptions()
    if spec.sim:   # the scene's own simulator settings (e.g. no-slip on slopes) win over the defaults
        options = replace(options, **spec.sim)
    substeps = int(round(spec.control_dt / options.timestep))
    if substeps < 1 or abs(substeps * options.timestep - spec.control_dt) > 1e-12:
        raise ConfigError(f"control_dt {spec.control_dt} must be a multiple of the physics timestep "
                          f"{options.timestep}", file=spec.file, key="control_dt")
    if isinstance(controller, Controller):
        ctrl = controller
        if ctrl.robot is not robot or abs(ctrl.dt - spec.control_dt) > 1e-12:
            raise ConfigError(f"controller '{ctrl.name}' was built for another robot or control_dt "
                              f"({ctrl.dt} s, scenario {spec.control_dt} s)", key="--controller")
        if mode is not None and ctrl.mode.value != str(getattr(mode, "value", mode)):
            raise ConfigError(f"mode '{mode}' differs from the controller's '{ctrl.mode.value}'", key="--mode")
        controller = ctrl.name
    else:
        if taskset is None and spec.taskset_variant is not None:  # the scene's own gains, where the robot has them
            from .controllers.taskset import taskset_variant_path
            taskset = taskset_variant_path(robot, controller, spec.taskset_variant)
        ctrl = make_controller(controller, robot, mode, spec.control_dt, taskset)
    if isinstance(model_error, (str, Path)):
        from .config import Section, load_yaml
        from .sim.model_error import parse_model_error

        model_error = parse_model_error(Section(load_yaml(model_error), str(model_error)))
    model_error = model_error if model_error is not None else spec.model_error
    try:
        sim = make_simulator(engine, robot, spec.terrain, ctrl.mode, options, spec.pushes, model_error)
    except ConfigError:
        raise
    except ValueError as exc:  # MuJoCo refuses the model built from the profile's URDF
        raise ConfigError(f"cannot build the MuJoCo model: {str(exc).splitlines()[0]}",
                          file=robot.profile.file) from None
    # what the controller sees: the simulator's measurement through the sensor model (ideal: unchanged)
    sensing = make_sensor_model(sensors if sensors is not None else spec.sensors, robot, spec.control_dt, seed)
    injector = FaultInjector(tuple(faults) + tuple(spec.faults), robot, spec.control_dt)

    if out is None:
        stamp = time.strftime("%Y%m%d-%H%M%S")
        out = Path("runs") / f"{spec.name}-{controller}-{ctrl.mode.value}-{robot.name}-{stamp}"
    run_dir = Path(out)
    if not overwrite and ((run_dir / "log.parquet").exists() or (run_dir / "summary.json").exists()):
        raise ConfigError(f"{run_dir} already holds a run; give another directory or overwrite it (--overwrite)",
                          key="--out")
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        (run_dir / ".write-test").touch()
        (run_dir / ".write-test").unlink()
    except OSError as exc:
        raise ConfigError(f"cannot write the run directory {run_dir}: {exc.strerror or exc}", key="--out") from None
    config = {"robot": robot.name, "robot_profile": robot.profile.file, "scenario": spec.name,
              "scenario_file": spec.file, "scenario_kind": spec.kind,
              **({"scenario_sizes": sizes} if (sizes := robot_sizes(spec.name, robot)) else {}),
              "controller": controller,
              "taskset_file": getattr(getattr(ctrl, "spec", None), "file", None) or None,
              "mode": ctrl.mode.value, "engine": engine,
              "duration_s": spec.duration or None, "control_dt_s": spec.control_dt,
              "sim": {"timestep": options.timestep, "integrator": options.integrator,
                      "noslip_iterations": options.noslip_iterations, "substeps": substeps,
                      "self_collision": options.self_collision},
              "pushes": [p.__dict__ for p in spec.pushes], "terrain": spec.terrain.kind,
              "scene": dataclasses.asdict(spec.terrain),
              "sensors": {**sensing.profile.__dict__, "seed": seed},
              "model_error": {"spec": model_error.__dict__ if model_error is not None else None,
                              "applied": sim.model_error},
              "versions": _versions()}
    (run_dir / "config.json").write_text(json.dumps(config, indent=2, default=str))

    # --- log layout
    rec = Recorder(run_dir / "log.parquet")
    qlab, vlab = _base_labels(robot)
    s_t = rec.add_channel("t")
    s_q = rec.add_channel("q", qlab)
    s_v = rec.add_channel("v", vlab)
    s_tau = rec.add_channel("tau", robot.joint_names)
    s_com = rec.add_channel("com", ["x", "y", "z"])
    s_vcom = rec.add_channel("com_vel", ["x", "y", "z"])
    s_ref = rec.add_channel("com_ref", ["x", "y", "z"])
    s_zmp = rec.add_channel("zmp_ref", ["x", "y", "z"])
    s_fref = {s: rec.add_channel(f"foot_ref_{s.value}", ["x", "y", "z"]) for s in Side}
    wl = ["fx", "fy", "fz", "mx", "my", "mz"]
    s_cw = {s: rec.add_channel(f"contact_{s.value}", wl) for s in Side}
    s_ft = {s: rec.add_channel(f"ft_{s.value}", wl) for s in Side}
    s_in = {s: rec.add_channel(f"in_contact_ref_{s.value}") for s in Side}
    # each pair of per-side channels is registered left then right, next to each other: written in one go
    s_cw_all, s_ft_all, s_in_all = (slice(d[Side.LEFT].start, d[Side.RIGHT].stop) for d in (s_cw, s_ft, s_in))
    # where Simulator.read_tick writes the ground truth: q, v, tau, both soles' wrenches, both F/T readings
    truth_dst = np.array([s_q.start, s_v.start, s_tau.start, s_cw_all.start, s_ft_all.start], dtype=np.int64)
    i_t = s_t.start
    in_contact = _ContactFlags()
    # the frame-task targets handed to the controller (e.g. teleoperation hands and head): position, rotation
    target_comps = ["x", "y", "z"] + [f"r{i}{j}" for i in range(3) for j in range(3)]
    s_targets = {name: rec.add_channel(f"target_{name}", target_comps) for name in scen.target_names}
    s_time = rec.add_channel("controller_time_us")
    extra = ctrl.log_channels()
    s_extra = [rec.add_channel(name, comps) for name, comps in extra.items()]
    # a scenario may log its own per-tick channels (e.g. the teleoperation command filter's interventions)
    scen_channels = scen.log_channels() if hasattr(scen, "log_channels") else {}
    s_scen = [rec.add_channel(name, comps) for name, comps in scen_channels.items()]
    s_probe = [[rec.add_channel(name, comps) for name, comps in p.attach(sim).items()] for p in probes]
    observers = [p for p in probes if hasattr(p, "observe")]
    s_est = (rec.add_channel("base_estimate_error", ["x", "y", "z", "rx", "ry", "rz"])
             if sensing.estimator is not None else None)
    s_fault = rec.add_channel("faults", list(injector.LOG_LABELS)) if injector.enabled else None
    # predicted falls from the measurement (capture point vs support polygon, tilt rate); optional safe stop
    predictor = FallPredictor(robot) if (predict_falls or safe_stop) else None
    s_fall = rec.add_channel("fall_prediction", list(FallPredictor.LOG_LABELS)) if predictor else None
    # paced to the wall clock: how late each tick started [ms] (0 when on time)
    s_late = rec.add_channel("lateness_ms") if realtime else None
    stopper = None

    model, data = robot.model, robot.model.createData()
    # the ground-truth CoM and its velocity: computed from the logged q and v for a whole row group at a time
    # (compiled, in the log's writer thread), or per tick by pinocchio for joint types the kernel lacks
    com_kernel = CenterOfMass(model)
    if com_kernel.supported and s_vcom.start == s_com.start + 3:
        def com_columns(block: np.ndarray, first: int = 0) -> None:
            com_kernel.write_rows(block, s_q.start, s_v.start, s_com.start)

        rec.derive(com_columns)
        # load the compiled kernel now: loading it at the first row group holds the interpreter for milliseconds
        com_columns(np.empty((0, len(rec.columns))))
    else:
        com_kernel = None
    q_true = sim.true_q()
    ts = getattr(ctrl, "spec", None)  # the controller's task set may carry its own step-adjustment settings
    if getattr(ts, "step_adjustment", None) and hasattr(scen, "adopt_step_adjustment"):
        scen.adopt_step_adjustment(dict(ts.step_adjustment), ts.file)
    if hasattr(scen, "offer_swing_pitch"):  # a walk plans the swing pitch only for a controller that takes it
        scen.offer_swing_pitch = getattr(ts, "swing_pitch_with_leg", True)
    scen.setup(q_true, pin.centerOfMass(model, data, q_true).copy())
    duration = spec.duration if spec.duration > 0 else scen.planned_duration
    n_ticks = int(round(duration / spec.control_dt))
    k_branch, n_branches = None, 0
    if branch is not None:
        k_branch = int(math.floor(branch.t / spec.control_dt + 1e-9))
        if not 0 < k_branch < n_ticks:
            raise ConfigError(f"branch point t = {branch.t} s outside the run (0, {duration}) s", key="branch")
        if not hasattr(os, "fork"):
            raise ConfigError("branching a run needs os.fork (Linux, macOS)", key="branch")
        rec.chunk = max(rec.chunk, k_branch + 1)  # nothing written to the file before the branches: they copy it
    fell, reason, error, interrupted = False, "", None, False
    ctrl_us = np.full(n_ticks, np.nan)

    def time_columns(block: np.ndarray, first: int) -> None:
        """Row k is tick k: its time (the state's, after the step) and the controller's step time, filled per row
        group (the same numbers as per tick)."""
        ticks = np.arange(first + 1, first + 1 + len(block))
        block[:, i_t] = ticks * spec.control_dt
        block[:, s_time.start] = ctrl_us[first:first + len(block)]

    rec.derive(time_columns)
    lateness = np.zeros(n_ticks) if realtime else None
    # a paced run's causes of lateness [ms]: how late each sleep returned (the machine), each tick's own time (the work)
    overslept, busy = (np.zeros(n_ticks), np.full(n_ticks, np.nan)) if realtime else (None, None)
    # a paced run: no cyclic garbage collection during the loop (a full collection stalls the interpreter for
    # milliseconds; the loop's objects are freed by reference counting), what exists now moved out of its reach
    gc_paused = realtime and gc.isenabled()
    if gc_paused:
        gc.collect()
        gc.freeze()
        gc.disable()
    # a paced run takes the interpreter back from the log's writer thread within 0.2 ms instead of Python's 5 ms
    # (the writer builds a row group's Arrow columns in Python while holding it)
    switch_interval = sys.getswitchinterval()
    if realtime:
        sys.setswitchinterval(min(switch_interval, 2e-4))
    # a paced loop asks for the real-time scheduling class, as a robot's control thread does, where it may: the
    # kernel's and other programs' threads no longer preempt it for milliseconds (it sleeps every tick, so they
    # run then; threads started before, e.g. the log's writer, keep the normal class)
    priority = _raise_priority() if realtime else None
    if priority is not None and priority[1]:
        rec.set_writer_priority(_REALTIME_PRIORITY - 5)
    wall0 = time.perf_counter()
    tick = 0
    observe = getattr(scen, "observe", None)
    try:
        if injector.enabled:
            injector.update(0.0, sim, ctrl)
        meas = sensing.measure(sim.measure())
        if injector.enabled:
            meas = injector.measurement(meas)
        try:
            ctrl.reset(meas, scen.references(0.0))
        except MissingReferenceError as exc:  # the scenario lacks what the controller's stabilizer needs
            raise ConfigError(f"scenario '{spec.name}' with controller '{controller}': {exc}",
                              file=spec.file) from None
        control_dt = spec.control_dt
        ideal_sensing = sensing.ideal  # the controller sees the simulator's measurement as it is
        faults_on = injector.enabled
        row = rec.row  # the row of this tick's log (the recorder hands out the next one at each commit)
        # the per-tick calls, looked up once
        references, ctrl_step, apply, physics = scen.references, ctrl.step, sim.apply, sim.step
        read_tick, measurement, log_values, commit = sim.read_tick, sim.measurement, ctrl.log_values, rec.commit
        for tick in range(n_ticks):
            t = tick * control_dt
            if tick == k_branch:
                approach = time.perf_counter() - wall0
                try:
                    got = _branch(branch, sim, rec, config)
                except Exception as exc:  # the plan's own error (not the controller's): raised as it is
                    raise _PlanError(exc) from None
                if isinstance(got, int):  # the parent: every branch has run; this run ends here
                    n_branches = got
                    break
                run_dir, wall0 = got, time.perf_counter() - approach  # a branch: its own run from here on
            if realtime and tick > 0:  # tick k starts at wall_start + k dt, or late
                now = time.perf_counter()
                if tick == 1:  # the clock starts after the first tick (one-off start-up work is not a delay)
                    wall_start = now - t
                else:  # the previous tick's own time, from its start to now
                    busy[tick - 1] = (now - started) * 1e3
                late = now - (wall_start + t)
                if late < 0:
                    time.sleep(-late)
                    started = time.perf_counter()
                    late = started - (wall_start + t)
                    if late > 0:  # the sleep returned after the tick's start: the machine's scheduling
                        overslept[tick] = late * 1e3
                else:
                    started = now
                if late > 0:
                    lateness[tick] = late * 1e3
                    if late > _MAX_CATCH_UP:  # a stall: resume from now rather than rush to catch up
                        wall_start += late
            if observe is not None:  # a scenario that re-plans from the measurement (e.g. step adjustment)
                observe(t, meas)
            refs = references(t)
            for p in observers:
                p.observe(t, refs)
            c0 = time.perf_counter()
            cmd = ctrl_step(meas, refs)
            ctrl_us[tick] = (time.perf_counter() - c0) * 1e6
            if faults_on:
                cmd = injector.safe_stop(meas, ctrl.mode, refs.contacts) or cmd
            if predictor is not None:
                fall_log = predictor.update(meas)
                if safe_stop and predictor.first_prediction_t is not None:
                    if stopper is None:  # joint-pd about the posture at the prediction, for good
                        from .controllers.joint_pd import JointPD

                        stopper = JointPD(robot, ctrl.mode, spec.control_dt)
                        stopper.q_ref = meas.q[7:].copy()
                    cmd = stopper.step(meas, refs)
            apply(cmd)
            physics(substeps)
            # ---- record the state after the step (ground truth) and what was commanded
            if predictor is not None:
                row[s_fall] = fall_log
            if s_late is not None:
                row[s_late] = lateness[tick]
            # the next tick's measurement, recorded with the state it belongs to: q, v, applied torque, contact
            # wrenches and F/T readings go into the row in the same call
            state, fs = read_tick(row, truth_dst)
            true_meas = measurement(state)  # ground truth before the sensor layer
            if com_kernel is None:  # else filled per row group from the logged q and v (below)
                row[s_com] = pin.centerOfMass(model, data, true_meas.q, true_meas.v, False)
                row[s_vcom] = data.vcom[0]
            if refs.com is not None:
                row[s_ref] = refs.com.position
            if refs.zmp is not None:
                row[s_zmp] = refs.zmp
            if refs.feet:
                for s, foot in refs.feet.items():
                    row[s_fref[s]] = foot.position
            if s_targets:
                for name, sl in s_targets.items():
                    target = refs.targets.get(name)
                    if target is not None:
                        cells = row[sl]
                        cells[:3] = target.position
                        if target.rotation is not None:
                            cells[3:] = target.rotation.reshape(-1)
            row[s_in_all] = in_contact[refs.contacts]
            meas = true_meas if ideal_sensing else sensing.measure(true_meas)
            if faults_on:
                row[s_fault] = injector.log
                injector.update((tick + 1) * spec.control_dt, sim, ctrl)
                meas = injector.measurement(meas)
            for sl, val in zip(s_extra, log_values()):
                row[sl] = val
            if s_scen:
                for sl, val in zip(s_scen, scen.log_values()):
                    row[sl] = val
            if s_est is not None:
                row[s_est] = sensing.base_error()
            for slices, p in zip(s_probe, probes):
                for sl, val in zip(slices, p.values()):
                    row[sl] = val
            try:
                row = commit()  # the next tick's row
            except OSError as exc:  # e.g. the disk is full: what was flushed stays readable
                raise LogWriteError(f"cannot write the log {run_dir / 'log.parquet'} at t = "
                                    f"{(tick + 1) * control_dt:.3f} s ({exc.strerror or exc}); the ticks written "
                                    "before are kept") from None
            if fs.fell:
                fell, reason = True, fs.reason
                break
            if progress is not None and tick % 100 == 0:
                progress((tick + 1) / n_ticks)
    except WbcError:
        _close_quietly(rec)
        raise
    except _PlanError as exc:
        _close_quietly(rec)
        raise exc.error
    except KeyboardInterrupt:  # Ctrl-C: stop here, keep the log and say so in the summary
        interrupted = True
    except Exception as exc:  # a crash in a controller: keep the log, say why
        if _from_interrupt(exc):  # Ctrl-C inside a compiled call, which re-raised it as another error
            interrupted = True
        else:
            fell, reason = True, f"error: {type(exc).__name__}: {exc}"
            error = traceback.format_exc()
    finally:
        _close_quietly(rec)
        if gc_paused:
            gc.enable()
            gc.unfreeze()
        sys.setswitchinterval(switch_interval)
        if priority is not None:
            _restore_priority(priority)
    wall = time.perf_counter() - wall0
    sim_time = (tick + (0 if n_branches else 1)) * spec.control_dt if n_ticks else 0.0
    summary = {
        "robot": robot.name, "scenario": spec.name, "controller": controller, "mode": ctrl.mode.value,
        "fell": fell, "fall_reason": reason or None, "interrupted": interrupted, "sim_time_s": sim_time,
        "duration_s": duration,
        "wall_time_s": wall, "real_time_factor": sim_time / wall if wall > 0 else None,
        **({"branches": n_branches} if branch is not None and not _BRANCH_CHILD else {}),
        "step_time_us": step_time_stats(ctrl_us[: tick + 1]),
        "controller_status": ctrl.status(),
        "sensors": {"profile": sensing.profile.name, "seed": seed, "dropped_ticks": sensing.n_dropped},
        "faults": injector.summary() if injector.enabled else None,
        "realtime": None if lateness is None else {
            **_lateness_summary(lateness[: tick + 1], spec.control_dt, sim_time, wall, overslept[: tick + 1],
                                busy[: tick + 1]),
            "scheduling": "real-time (SCHED_FIFO)" if priority and priority[1] else "normal (real-time class not permitted)"},
        "fall_prediction": None if predictor is None else {
            "first_prediction_t": predictor.first_prediction_t, "safe_stop": safe_stop,
            "time_to_fall_s": (sim_time - predictor.first_prediction_t
                               if fell and predictor.first_prediction_t is not None else None),
            "false_alarm": bool(predictor.first_prediction_t is not None and not fell)},
        "metrics": {},
    }
    log = {}
    if rec.rows_written:
        log = read_log(run_dir / "log.parquet")
        try:
            scen_metrics = scen.metrics(log)
            paper = compute_run_metrics(log, robot, dt=spec.control_dt,
                                        distance_planned_m=scen_metrics.get("planned_distance_m"))
            probe_metrics = {k: v for p in probes for k, v in p.metrics(log).items()}
            summary["metrics"] = {**paper, **_common_metrics(log), **scen_metrics, **probe_metrics}
        except Exception as exc:  # metrics must never lose the run
            summary["metrics_error"] = f"{type(exc).__name__}: {exc}"
    try:
        if error:
            (run_dir / "error.txt").write_text(error)
        (run_dir / "summary.json").write_text(json.dumps(summary, indent=2))
    except OSError as exc:
        raise LogWriteError(f"cannot write {run_dir / 'summary.json'} ({exc.strerror or exc}); the log is kept") from None
    if interrupted:
        raise RunInterrupted(f"interrupted at t = {sim_time:.3f} s; {run_dir} keeps the log and the summary up to there")
    return RunResult(run_dir, summary, log)


#: [s] a paced run that falls further behind than this resumes from the wall clock (the stall is counted)
#: instead of running the simulation faster than real time to catch up
_MAX_CATCH_UP = 0.005


#: the paced loop's real-time priority (SCHED_FIFO, 1-99): low, above every normal thread and below the kernel's own
#: real-time threads; the log's writer thread runs 5 below it
_REALTIME_PRIORITY = 10


def _raise_priority() -> tuple | None:
    """Put the calling thread in the real-time class (SCHED_FIFO at `_REALTIME_PRIORITY`) when the system allows;
    (the previous policy and parameters, whether it was raised), or None where the call does not exist."""
    if not hasattr(os, "sched_setscheduler"):
        return None
    before = (os.sched_getscheduler(0), os.sched_getparam(0))
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(_REALTIME_PRIORITY))
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


def _lateness_summary(late_ms: np.ndarray, dt: float, sim_time: float, wall: float, overslept_ms: np.ndarray,
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


def _branch(branch: BranchPoint, sim: Simulator, rec: Recorder, config: dict) -> Path | int:
    """At the branch point. In the parent, run `branch.plan()`'s branches one by one, each in a forked child,
    and return how many ran. In a child, set up its branch (pushes, run directory and config, log file: the
    rows so far are in memory) and return its run directory: the child then runs on as a normal run and exits
    at the end of `run`."""
    global _BRANCH_CHILD, _BRANCH_DIR
    plan = branch.plan()
    try:
        b = next(plan)
    except StopIteration:
        return 0
    n = 0
    while True:
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            _BRANCH_CHILD = True
            out = _BRANCH_DIR = Path(b.out)
            out.mkdir(parents=True, exist_ok=True)
            for stale in ("summary.json", "error.txt", "log.parquet"):
                (out / stale).unlink(missing_ok=True)
            sim.set_pushes(tuple(sim.pushes) + tuple(b.pushes))
            cfg = {**config, "pushes": [p.__dict__ for p in sim.pushes]}
            (out / "config.json").write_text(json.dumps(cfg, indent=2, default=str))
            rec.path = out / "log.parquet"
            return out
        _, status = os.waitpid(pid, 0)
        n += 1
        code = os.waitstatus_to_exitcode(status)
        try:
            summary = json.loads((Path(b.out) / "summary.json").read_text())
        except (OSError, ValueError):
            why = ""
            try:
                why = ": " + (Path(b.out) / "error.txt").read_text().strip().splitlines()[-1]
            except (OSError, IndexError):
                pass
            summary = {"error": f"the branch's process ended with exit code {code} and no summary{why}"}
        try:
            b = plan.send(summary)
        except StopIteration:
            return n


class _PlanError(Exception):
    """An error raised by a branch plan (carried past the loop's handler of controller crashes)."""

    def __init__(self, error: Exception):
        super().__init__(str(error))
        self.error = error


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


class LogWriteError(WbcError):
    """The run directory could not be written (disk full, removed, no permission) during a run."""


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C during a run: the run directory keeps the log and the summary up to the interruption."""


def _close_quietly(rec: Recorder) -> None:
    try:
        rec.close()
    except OSError:  # the log cannot be completed (disk full): what was flushed stays readable
        pass


def _common_metrics(log: dict[str, np.ndarray]) -> dict:
    z = log["q.z"]
    z0 = z[0]
    out = {"base_height_change_m": float(z[-1] - z0), "base_height_max_deviation_m": float(np.abs(z - z0).max()),
           "com_final_m": [float(log[f"com.{a}"][-1]) for a in "xyz"]}
    if "base_estimate_error.x" in log:  # the sensor model estimated the base: how far from the truth
        pos = np.linalg.norm(np.column_stack([log[f"base_estimate_error.{a}"] for a in "xyz"]), axis=1)
        rot = np.linalg.norm(np.column_stack([log[f"base_estimate_error.r{a}"] for a in "xyz"]), axis=1)
        out["base_estimate_error"] = {"position_rms_m": float(np.sqrt(np.mean(pos ** 2))),
                                      "position_max_m": float(pos.max()), "position_final_m": float(pos[-1]),
                                      "orientation_max_rad": float(rot.max())}
    return out


def _versions() -> dict:
    import mujoco

    out = {"python": platform.python_version(), "pinocchio": pin.__version__, "mujoco": mujoco.__version__,
           "numpy": np.__version__}
    for mod in ("daqp", "proxsuite"):
        try:
            out[mod] = __import__(mod).__version__
        except Exception:  # pragma: no cover - optional info only
            pass
    return out
