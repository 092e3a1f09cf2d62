"""The run loop: scenario -> controller -> simulator at the control rate, every tick recorded.

A run directory holds config.json (everything resolved), log.parquet (one row per control tick) and
summary.json. A run that falls or fails still writes its log up to the failure and says why.

`run` resolves its options into a `RunConfig`, builds the parts (robot, scenario, controller, simulator, sensor
model, faults), the run directory and its config, then a `wbcbench.loop.RunLoop` whose ticks are named phases:
the options that add per-tick work (probes, sensors, faults, fall prediction and safe stop, wall-clock pacing,
a branch point, the caller's own hooks) are hooks registered on the phases they need (`wbcbench.loop_hooks`).
"""

from __future__ import annotations

import dataclasses
import json
import platform
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from . import branching
from .branching import Branch, BranchHook, BranchPoint
from .controllers.base import Controller, make_controller
from .errors import ConfigError
from .faults import FaultInjector
from .loop import PHASES, EndRun, Hook, LogLayout, LogWriteError, LoopOutcome, RunLoop, Tick
from .loop_hooks import FallHook, FaultHook, PacingHook, ProbeHook, SensorHook
from .metrics.from_log import compute_run_metrics
from .recorder import Recorder, read_log
from .robots import Robot, load_robot
from .scenarios import Scenario, load_scenario
from .scenarios.base import robot_sizes
from .sensing import make_sensor_model
from .sim.engines import make_simulator
from .sim.model import SimOptions
from .sim.simulator import Simulator
from .stabilizers.base import MissingReferenceError
from .tasks.placements import CenterOfMass

__all__ = ["run", "run_config", "RunConfig", "RunResult", "Branch", "BranchPoint", "Hook", "Tick", "PHASES",
           "EndRun", "LogWriteError", "RunInterrupted", "step_time_stats"]


@dataclass
class RunResult:
    run_dir: Path
    summary: dict
    log: dict[str, np.ndarray] = field(repr=False, default_factory=dict)


def step_time_stats(us: np.ndarray) -> dict:
    us = us[np.isfinite(us)]
    if us.size == 0:
        return {"median": None, "p99": None, "max": None, "mean": None}
    return {"median": float(np.median(us)), "p99": float(np.percentile(us, 99)), "max": float(us.max()),
            "mean": float(us.mean())}


@dataclass(frozen=True)
class RunConfig:
    """Everything a run is asked for (the arguments of `run`, which documents them)."""

    scenario: str | Scenario
    controller: str | Controller
    robot: str | Robot = "talos"
    mode: str | None = None
    duration: float | None = None
    out: str | Path | None = None
    progress: Callable[[float], None] | None = None
    sim_options: SimOptions | None = None
    probes: tuple = ()
    taskset: str | Path | None = None
    sensors: object = None
    seed: int = 0
    model_error: object = None
    faults: tuple = ()
    predict_falls: bool = False
    safe_stop: bool = False
    overwrite: bool = False
    realtime: bool = False
    branch: BranchPoint | None = None
    hooks: tuple = ()
    engine: str = "mujoco"
    realism: object = None


def run(scenario: str | Scenario, controller: str | Controller, robot: str | Robot = "talos",
        mode: str | None = None, duration: float | None = None, out: str | Path | None = None,
        progress: Callable[[float], None] | None = None, sim_options: SimOptions | None = None,
        probes: Sequence = (), taskset: str | Path | None = None, sensors=None, seed: int = 0,
        model_error=None, faults: Sequence = (), predict_falls: bool = False, safe_stop: bool = False,
        overwrite: bool = False, realtime: bool = False, branch: BranchPoint | None = None,
        hooks: Sequence = (), engine: str = "mujoco", realism=None) -> RunResult:
    """Run one scenario with one controller; returns the summary (and the log, read back).

    `controller` is a registered name, or a controller already built for this robot at the scenario's
    control_dt (its `mode` is used; `mode` must then be None or the same). `probes` observe the simulator:
    each has `attach(sim) -> {channel: components}` (called once), `values() -> list` (after every tick,
    logged in those channels) and `metrics(log) -> dict` (merged into the summary's metrics); e.g.
    `wbcbench.sim.self_collision.SelfCollisionProbe`. A probe may also have `observe(t, refs)`, called with the
    references handed to the controller every tick (e.g. the live view, `wbcbench.viz.live.LiveView`).
    `branch`: continue the run several times from one state (`BranchPoint`).
    `hooks`: the caller's own part in each tick, `wbcbench.loop.Hook` objects or `(phase, callable(tick))`
    pairs, called after the built-in work of their phases (`wbcbench.loop` documents the phases).
    `engine`: the physics engine (`wbcbench.sim.engines`: mujoco, dart or a plugin's).
    `realism`: the simulated robot's hidden hardware (`wbcbench.sim.realism`: a preset name, file or `Realism`).
    """
    return run_config(RunConfig(scenario, controller, robot, mode, duration, out, progress, sim_options,
                                tuple(probes), taskset, sensors, seed, model_error, tuple(faults), predict_falls,
                                safe_stop, overwrite, realtime, branch, tuple(hooks), engine, realism))


def run_config(cfg: RunConfig) -> RunResult:
    """`run` with its options in a `RunConfig`. In a branch's child process (`BranchPoint`) this never returns:
    the process ends at the end of its run."""
    try:
        result = _run(cfg)
    except BaseException:
        if branching.is_branch_child():  # a branch's process never returns into its parent's code
            branching.branch_exit(1, traceback.format_exc())
        raise
    if branching.is_branch_child():
        branching.branch_exit(0, None)
    return result


@dataclass
class _Parts:
    """What a run is made of, resolved from its `RunConfig`."""

    robot: Robot
    scen: Scenario
    spec: object
    options: SimOptions
    substeps: int
    ctrl: Controller
    controller: str
    model_error: object
    sim: Simulator
    sensing: object
    injector: FaultInjector


def _run(cfg: RunConfig) -> RunResult:
    p = _build(cfg)
    run_dir = _make_run_dir(cfg, p)
    config = _config(cfg, p)
    (run_dir / "config.json").write_text(json.dumps(config, indent=2, default=str))
    loop, hooks = _make_loop(cfg, p, run_dir, config)
    duration = _setup_scenario(p)
    loop.prepare(int(round(duration / p.spec.control_dt)), duration)
    outcome = loop.execute(_reset(p))
    summary = _summary(cfg, p, loop, outcome, hooks)
    log = _add_metrics(summary, loop.run_dir, loop.recorder, p, hooks["probes"].probes)
    try:
        if outcome.error:
            (loop.run_dir / "error.txt").write_text(outcome.error)
        (loop.run_dir / "summary.json").write_text(json.dumps(summary, indent=2))
    except OSError as exc:
        raise LogWriteError(f"cannot write {loop.run_dir / 'summary.json'} ({exc.strerror or exc}); the log is "
                            "kept") from None
    if outcome.interrupted:
        raise RunInterrupted(f"interrupted at t = {summary['sim_time_s']:.3f} s; {loop.run_dir} keeps the log and the "
                             "summary up to there")
    return RunResult(loop.run_dir, summary, log)


def _build(cfg: RunConfig) -> _Parts:
    robot = load_robot(cfg.robot) if isinstance(cfg.robot, str) else cfg.robot
    scen = load_scenario(cfg.scenario, robot, cfg.duration) if isinstance(cfg.scenario, str) else cfg.scenario
    spec = scen.spec
    options = cfg.sim_options or SimOptions()
    if spec.sim:   # the scene's own simulator settings (e.g. no-slip on slopes) win over the defaults
        options = replace(options, **spec.sim)
    substeps = int(round(spec.control_dt / options.timestep))
    if substeps < 1 or abs(substeps * options.timestep - spec.control_dt) > 1e-12:
        raise ConfigError(f"control_dt {spec.control_dt} must be a multiple of the physics timestep "
                          f"{options.timestep}", file=spec.file, key="control_dt")
    ctrl, controller = _controller(cfg, robot, spec)
    if cfg.realism is not None:  # the hidden actuator chains and flexibilities, in the simulator only
        from .sim.realism import load_realism
        if cfg.engine != "mujoco":
            raise ConfigError(f"a realism preset needs the mujoco engine, not '{cfg.engine}'", key="--realism")
        options = replace(options, realism=load_realism(cfg.realism, robot))
    model_error = cfg.model_error
    if isinstance(model_error, (str, Path)):
        from .config import Section, load_yaml
        from .sim.model_error import parse_model_error

        model_error = parse_model_error(Section(load_yaml(model_error), str(model_error)))
    model_error = model_error if model_error is not None else spec.model_error
    try:
        sim = make_simulator(cfg.engine, robot, spec.terrain, ctrl.mode, options, spec.pushes, model_error)
    except ConfigError:
        raise
    except ValueError as exc:  # MuJoCo refuses the model built from the profile's URDF
        raise ConfigError(f"cannot build the MuJoCo model: {str(exc).splitlines()[0]}",
                          file=robot.profile.file) from None
    # what the controller sees: the simulator's measurement through the sensor model (ideal: unchanged)
    sensors = cfg.sensors if cfg.sensors is not None else getattr(options.realism, "sensors", None) or spec.sensors
    sensing = make_sensor_model(sensors, robot, spec.control_dt, cfg.seed)
    injector = FaultInjector(tuple(cfg.faults) + tuple(spec.faults), robot, spec.control_dt)
    return _Parts(robot, scen, spec, options, substeps, ctrl, controller, model_error, sim, sensing, injector)


def _controller(cfg: RunConfig, robot: Robot, spec) -> tuple[Controller, str]:
    """The run's controller and its name: the one given (checked against the robot and control period) or one
    made from the registry (with the scene's task-set variant where the robot has one)."""
    controller, mode, taskset = cfg.controller, cfg.mode, cfg.taskset
    if isinstance(controller, Controller):
        ctrl = controller
        if ctrl.robot is not robot or abs(ctrl.dt - spec.control_dt) > 1e-12:
            raise ConfigError(f"controller '{ctrl.name}' was built for another robot or control_dt "
                              f"({ctrl.dt} s, scenario {spec.control_dt} s)", key="--controller")
        if mode is not None and ctrl.mode.value != str(getattr(mode, "value", mode)):
            raise ConfigError(f"mode '{mode}' differs from the controller's '{ctrl.mode.value}'", key="--mode")
        return ctrl, ctrl.name
    if taskset is None and spec.taskset_variant is not None:  # the scene's own gains, where the robot has them
        from .controllers.taskset import taskset_variant_path
        taskset = taskset_variant_path(robot, controller, spec.taskset_variant)
    return make_controller(controller, robot, mode, spec.control_dt, taskset), controller


def _make_run_dir(cfg: RunConfig, p: _Parts) -> Path:
    out = cfg.out
    if out is None:
        stamp = time.strftime("%Y%m%d-%H%M%S")
        out = Path("runs") / f"{p.spec.name}-{p.controller}-{p.ctrl.mode.value}-{p.robot.name}-{stamp}"
    run_dir = Path(out)
    if not cfg.overwrite and ((run_dir / "log.parquet").exists() or (run_dir / "summary.json").exists()):
        raise ConfigError(f"{run_dir} already holds a run; give another directory or overwrite it (--overwrite)",
                          key="--out")
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        (run_dir / ".write-test").touch()
        (run_dir / ".write-test").unlink()
    except OSError as exc:
        raise ConfigError(f"cannot write the run directory {run_dir}: {exc.strerror or exc}", key="--out") from None
    return run_dir


def _config(cfg: RunConfig, p: _Parts) -> dict:
    """config.json: everything the run resolved."""
    robot, spec, options, ctrl = p.robot, p.spec, p.options, p.ctrl
    return {"robot": robot.name, "robot_profile": robot.profile.file, "scenario": spec.name,
            "scenario_file": spec.file, "scenario_kind": spec.kind,
            **({"scenario_sizes": sizes} if (sizes := robot_sizes(spec.name, robot)) else {}),
            "controller": p.controller,
            "taskset_file": getattr(getattr(ctrl, "spec", None), "file", None) or None,
            "mode": ctrl.mode.value, "engine": cfg.engine,
            "duration_s": spec.duration or None, "control_dt_s": spec.control_dt,
            "sim": {"timestep": options.timestep, "integrator": options.integrator,
                    "noslip_iterations": options.noslip_iterations, "substeps": p.substeps,
                    "self_collision": options.self_collision},
            "pushes": [push.__dict__ for push in spec.pushes], "terrain": spec.terrain.kind,
            "scene": dataclasses.asdict(spec.terrain),
            "sensors": {**p.sensing.profile.__dict__, "seed": cfg.seed},
            "model_error": {"spec": p.model_error.__dict__ if p.model_error is not None else None,
                            "applied": p.sim.model_error},
            **({"realism": options.realism.describe()} if options.realism is not None else {}),
            "versions": _versions()}


def _make_loop(cfg: RunConfig, p: _Parts, run_dir: Path, config: dict) -> tuple[RunLoop, dict]:
    """The run's loop, its log layout and hooks: the built-in ones the run asks for, in the log's column order
    (probes, sensors, faults, fall prediction; a branch point; pacing), then the caller's."""
    robot, sim = p.robot, p.sim
    rec = Recorder(run_dir / "log.parquet")
    layout = LogLayout(rec, robot, p.scen, p.ctrl)
    # the ground-truth CoM and its velocity: computed from the logged q and v for a whole row group at a time
    # (compiled, in the log's writer thread), or per tick by pinocchio for joint types the kernel lacks
    model, data = robot.model, robot.model.createData()
    com_kernel, com = CenterOfMass(model), None
    if not (com_kernel.supported and layout.com_vel.start == layout.com.start + 3):
        def com(q, v):
            return pin.centerOfMass(model, data, q, v, False), data.vcom[0]

    loop = RunLoop(plant=sim, controller=p.ctrl, scenario=p.scen, recorder=rec, layout=layout,
                   dt=p.spec.control_dt, substeps=p.substeps, run_dir=run_dir, progress=cfg.progress, com=com)
    hooks = {"probes": ProbeHook(cfg.probes + _realism_probes(p)), "sensors": SensorHook(p.sensing),
             "faults": FaultHook(p.injector) if p.injector.enabled else None,
             "fall": FallHook(robot, cfg.safe_stop) if (cfg.predict_falls or cfg.safe_stop) else None,
             "branch": BranchHook(cfg.branch, config) if cfg.branch is not None else None,
             "pacing": PacingHook() if cfg.realtime else None}
    for hook in [h for h in hooks.values() if h is not None] + list(cfg.hooks):
        loop.add_hook(hook)
    if com is None:
        q0, v0, c0 = layout.q.start, layout.v.start, layout.com.start

        def com_columns(block: np.ndarray, first: int = 0) -> None:
            com_kernel.write_rows(block, q0, v0, c0)

        rec.derive(com_columns)
        # load the compiled kernel now: loading it at the first row group holds the interpreter for milliseconds
        com_columns(np.empty((0, len(rec.columns))))
    return loop, hooks


def _realism_probes(p: _Parts) -> tuple:
    from .sim.realism import RealismProbe
    return (RealismProbe(),) if p.options.realism is not None else ()


def _setup_scenario(p: _Parts) -> float:
    """The scenario planned from the start state (with the controller's own step adjustment and swing pitch where
    it has them); the run's duration [s]."""
    scen = p.scen
    q_true = p.sim.true_q()
    ts = getattr(p.ctrl, "spec", None)  # the controller's task set may carry its own step-adjustment settings
    if getattr(ts, "step_adjustment", None) and hasattr(scen, "adopt_step_adjustment"):
        scen.adopt_step_adjustment(dict(ts.step_adjustment), ts.file)
    if hasattr(scen, "offer_swing_pitch"):  # a walk plans the swing pitch only for a controller that takes it
        scen.offer_swing_pitch = getattr(ts, "swing_pitch_with_leg", True)
    model = p.robot.model
    scen.setup(q_true, pin.centerOfMass(model, model.createData(), q_true).copy())
    return p.spec.duration if p.spec.duration > 0 else scen.planned_duration


def _reset(p: _Parts) -> Callable:
    """The controller's reset on the first measurement, a missing reference named as the scenario's."""
    def reset(meas) -> None:
        try:
            p.ctrl.reset(meas, p.scen.references(0.0))
        except MissingReferenceError as exc:  # the scenario lacks what the controller's stabilizer needs
            raise ConfigError(f"scenario '{p.spec.name}' with controller '{p.controller}': {exc}",
                              file=p.spec.file) from None
    return reset


def _summary(cfg: RunConfig, p: _Parts, loop: RunLoop, out: LoopOutcome, hooks: dict) -> dict:
    dt, k = p.spec.control_dt, out.k
    branch, pacing, fall = hooks["branch"], hooks["pacing"], hooks["fall"]
    n_branches = branch.n_branches if branch is not None else 0
    sim_time = (k + (0 if n_branches else 1)) * dt if loop.n_ticks else 0.0
    wall = out.wall
    predictor = fall.predictor if fall is not None else None
    return {
        "robot": p.robot.name, "scenario": p.spec.name, "controller": p.controller, "mode": p.ctrl.mode.value,
        **({"realism": p.options.realism.name} if p.options.realism is not None else {}),
        "fell": out.fell, "fall_reason": out.reason or None, "interrupted": out.interrupted, "sim_time_s": sim_time,
        "duration_s": loop.duration,
        "wall_time_s": wall, "real_time_factor": sim_time / wall if wall > 0 else None,
        **({"branches": n_branches} if branch is not None and not branching.is_branch_child() else {}),
        "step_time_us": step_time_stats(loop.ctrl_us[: k + 1]),
        "controller_status": p.ctrl.status(),
        "sensors": {"profile": p.sensing.profile.name, "seed": cfg.seed, "dropped_ticks": p.sensing.n_dropped},
        "faults": p.injector.summary() if p.injector.enabled else None,
        "realtime": None if pacing is None else pacing.summary(k, dt, sim_time, wall),
        "fall_prediction": None if predictor is None else {
            "first_prediction_t": predictor.first_prediction_t, "safe_stop": cfg.safe_stop,
            "time_to_fall_s": (sim_time - predictor.first_prediction_t
                               if out.fell and predictor.first_prediction_t is not None else None),
            "false_alarm": bool(predictor.first_prediction_t is not None and not out.fell)},
        "metrics": {},
    }


def _add_metrics(summary: dict, run_dir: Path, rec: Recorder, p: _Parts, probes: Sequence) -> dict:
    """The log read back, and its metrics into the summary (the scenario's, the papers', the probes')."""
    log = {}
    if rec.rows_written:
        log = read_log(run_dir / "log.parquet")
        try:
            scen_metrics = p.scen.metrics(log)
            realism = p.options.realism
            motors = realism.motors.describe(realism.joints) if getattr(realism, "motors", None) else None
            paper = compute_run_metrics(log, p.robot, dt=p.spec.control_dt,
                                        distance_planned_m=scen_metrics.get("planned_distance_m"), motors=motors)
            probe_metrics = {k: v for probe in probes for k, v in probe.metrics(log).items()}
            summary["metrics"] = {**paper, **_common_metrics(log), **scen_metrics, **probe_metrics}
        except Exception as exc:  # metrics must never lose the run
            summary["metrics_error"] = f"{type(exc).__name__}: {exc}"
    return log


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C during a run: the run directory keeps the log and the summary up to the interruption."""


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
