"""One sweep cell: apply its parameters (overridden scenario / task-set YAML written into the cell directory and
loaded from there, so every override is validated like a file), run it, and return one results-table row."""

from __future__ import annotations

import json
import time
import traceback
from dataclasses import fields
from pathlib import Path

import numpy as np
import yaml

from ..config import load_yaml
from ..errors import ConfigError

DONE_FILE = "cell.json"
# columns that measure the machine, not the controller: equal cells may differ there
TIMING_PREFIXES = ("wall_time_s", "real_time_factor", "step_time_us.", "metrics.compute_time_us.",
                   "cell_wall_s")


def _split(params: dict, prefix: str) -> dict:
    return {k[len(prefix):]: v for k, v in params.items() if k.startswith(prefix)}


def prepare(params: dict, cell_dir: Path):
    """Build (scenario path, controller, robot, sim options, duration, mode) for `params`; writes scenario.yaml
    and taskset.yaml into `cell_dir` when they are overridden. ConfigError on an unknown key path or a value the
    loaders reject."""
    from ..controllers.base import available_controllers
    from ..controllers.taskset import load_taskset, taskset_path, taskset_variant_path
    from ..robots import load_robot
    from ..scenarios import load_scenario
    from ..scenarios.base import scenario_path
    from ..sim.model import SimOptions
    from .overrides import apply_overrides

    cell_dir.mkdir(parents=True, exist_ok=True)
    robot_src = str(params.get("robot", "talos"))
    prof_over = _split(params, "profile.")
    if prof_over:
        from ..robots.profile import PROFILE_DIR
        src = Path(robot_src) if robot_src.endswith((".yaml", ".yml")) else PROFILE_DIR / f"{robot_src}.yaml"
        if not src.exists():
            from ..robots import available_robots
            from ..errors import UnknownNameError
            raise UnknownNameError("robot", robot_src, available_robots(), key="robot")
        robot_src = str(cell_dir / "profile.yaml")
        Path(robot_src).write_text(yaml.safe_dump(apply_overrides(load_yaml(src), prof_over, str(src)),
                                                  sort_keys=False))
    robot = load_robot(robot_src)
    scen_src = scenario_path(str(params["scenario"]))
    scen_over = _split(params, "scenario.")
    scen_file = scen_src
    if scen_over:
        data = apply_overrides(load_yaml(scen_src), scen_over, str(scen_src))
        data.setdefault("name", scen_src.stem)
        scen_file = cell_dir / "scenario.yaml"
        scen_file.write_text(yaml.safe_dump(data, sort_keys=False))
    duration = params.get("duration")
    scen = load_scenario(str(scen_file), robot, float(duration) if duration is not None else None)
    name = str(params["controller"])
    ctrls = available_controllers()
    if name not in ctrls:
        from ..errors import UnknownNameError
        raise UnknownNameError("controller", name, ctrls, key="controller")
    ts_over = _split(params, "taskset.")
    ts_file = params.get("taskset")
    controller: object = name
    if ts_over or ts_file:
        variant = (taskset_variant_path(robot, name, scen.spec.taskset_variant)
                   if scen.spec.taskset_variant is not None else None)   # the task set the scene runs with
        src = Path(ts_file) if ts_file else (variant or taskset_path(robot, name))
        data = apply_overrides(load_yaml(src), ts_over, str(src))
        dst = cell_dir / "taskset.yaml"
        dst.write_text(yaml.safe_dump(data, sort_keys=False))
        cls = ctrls[name]
        if "taskset" not in cls.__init__.__code__.co_varnames:
            raise ConfigError(f"controller '{name}' has no task set", key="taskset")
        from ..controllers.ik import MAX_LEVELS
        from ..sim.model import ActuationMode
        spec = load_taskset(dst, robot, max_level=MAX_LEVELS if name == "ik" else 1)
        try:
            mode = ActuationMode(params.get("mode") or cls.default_mode)
        except ValueError:
            raise ConfigError(f"unknown mode '{params.get('mode')}'; allowed: "
                              f"{', '.join(m.value for m in ActuationMode)}", key="mode") from None
        controller = cls(robot, mode, scen.spec.control_dt, taskset=spec)
    if params.get("realism") is not None:   # the preset's file and key in the error, before any cell runs
        _check_realism(params, robot, ctrls[name], controller)
    sim_over = _split(params, "sim.")
    allowed = {f.name for f in fields(SimOptions)} - {"realism"}
    for k in sim_over:
        if k not in allowed:
            raise ConfigError(f"unknown simulator option '{k}'; allowed: {', '.join(sorted(allowed))}",
                              key=f"sim.{k}")
    options = SimOptions(**sim_over)
    return scen, controller, robot, options, params.get("mode")


def _check_realism(params: dict, robot, cls, controller) -> None:
    """A cell's realism preset: loadable for its robot, on the mujoco engine, with a torque- or position-mode
    controller (the hidden joints sit behind the actuator, which the SPD law cannot have)."""
    from ..sim.model import ActuationMode
    from ..sim.realism import check_realism

    check_realism(params["realism"], robot, str(params.get("engine") or "mujoco"), key="realism")
    mode = getattr(controller, "mode", None) or params.get("mode") or cls.default_mode
    try:
        mode = ActuationMode(getattr(mode, "value", mode))
    except ValueError:
        raise ConfigError(f"unknown mode '{mode}'; allowed: {', '.join(m.value for m in ActuationMode)}",
                          key="mode") from None
    if mode is ActuationMode.SPD:
        raise ConfigError("a realism preset needs torque or position mode, not spd", key="mode")


def flatten(d: dict, prefix: str = "") -> dict:
    """Nested summary -> {"a.b.c": scalar}; lists of numbers become JSON strings, other lists are dropped."""
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        elif isinstance(v, (bool, int, float, str)) or v is None:
            out[key] = v
        elif isinstance(v, (list, tuple)) and all(isinstance(x, (int, float)) for x in v):
            out[key] = json.dumps(v)
    return out


def run_cell(params: dict, cell_dir: str, code_version: str, cell_id: str, progress=None) -> dict:
    """Run one cell into `cell_dir` and return its row (also written to cell.json, the cell's done marker).
    Any exception is caught and recorded (status 'error'); the sweep goes on."""
    from ..runner import run

    t0 = time.perf_counter()
    d = Path(cell_dir)
    row = {"cell_id": cell_id, **{f"param.{k}": v for k, v in params.items()}, "code_version": code_version}
    try:
        if params.get("seed") is not None:
            np.random.seed(int(params["seed"]))
        scen, controller, robot, options, mode = prepare(params, d)
        result = run(scen, controller, robot, mode if not hasattr(controller, "step") else None,
                     None, d / "run", sim_options=options, progress=progress, overwrite=True,
                     seed=int(params.get("seed") or 0), engine=str(params.get("engine") or "mujoco"),
                     realism=params.get("realism"))
        summary = result.summary
        row.update(flatten({k: v for k, v in summary.items()
                            if k not in ("robot", "scenario", "controller", "controller_status")}))
        reason = summary.get("fall_reason") or ""
        row["status"] = "error" if reason.startswith("error:") else ("fell" if summary.get("fell") else "ok")
        row["error"] = reason[len("error: "):] if reason.startswith("error:") else None
    except Exception as exc:  # a crashed cell is recorded, never fatal
        row["status"] = "error"
        row["error"] = f"{type(exc).__name__}: {exc}"
        (d / "error.txt").write_text(traceback.format_exc())
    row["cell_wall_s"] = time.perf_counter() - t0
    d.mkdir(parents=True, exist_ok=True)
    (d / DONE_FILE).write_text(json.dumps(row, indent=1, default=str))
    return row
