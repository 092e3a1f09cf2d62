"""The envelope search: per (controller, axis), bisection between the axis's easy value (passes) and its hard one
for the value nearest the hard end at which the controller still completes the scenario.

A trial passes when the run ends without a fall or an error and its final CoM is within `tolerance` of the planned
CoM (the push protocol's criterion, wbcbench.robustness.push). Each trial is a sweep cell (wbcbench.study.cell:
scenario.yaml generated from the axis value, profile overrides, run/ a normal run directory, cell.json its row)
plus verdict.json; a trial with a verdict is not run again, so a killed search restarted on the same --out resumes.
The (controller, axis) searches run on the sweep's executors (one process, a process pool, or Ray).

Bisection: the hard value first (passing it: 'limit reached', the envelope is at least the range), then the easy
one (failing it: the envelope is below the range), then the midpoint of the bracket until the bracket is no wider
than the resolution. The result is the last passing value and the first failing one, with the failing trial's
failure mode: fell, QP infeasible, planner refused, off the plan (final CoM error beyond the bound), error.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import yaml

from ..errors import ConfigError

__all__ = ["EnvelopeResult", "EnvelopeStudy", "run_envelope", "run_trial", "search_axis"]

VERDICT_FILE = "verdict.json"


@dataclass(frozen=True)
class EnvelopeStudy:
    axes: tuple[str, ...]
    controllers: tuple[str, ...]
    robot: str = "talos"
    ranges: dict = field(default_factory=dict)        # axis -> (easy, hard)
    resolutions: dict = field(default_factory=dict)   # axis -> bracket width
    tolerance: float = 0.10                           # [m] final CoM error bound
    seed: int = 0
    engine: str = "mujoco"
    realism: str | None = None                        # realism preset of every trial (wbcbench.sim.realism)

    def range_of(self, axis) -> tuple[float, float]:
        return tuple(self.ranges.get(axis.name, (axis.easy, axis.hard)))

    def resolution_of(self, axis) -> float:
        return float(self.resolutions.get(axis.name, axis.resolution))


@dataclass
class EnvelopeResult:
    controller: str
    axis: str
    unit: str
    largest: bool
    easy: float
    hard: float
    resolution: float
    limit: float | None          # last passing value (None: even the easy value failed)
    first_failure: float | None  # first failing value (None: the hard value passed)
    mode: str                    # failure mode at first_failure, or 'limit reached' / 'fails at the easy value'
    reason: str
    trials: list = field(default_factory=list)   # [value, passed, mode, reason, trial dir]
    wall_s: float = 0.0


def trial_dir(out: Path, robot: str, controller: str, axis: str, value: float) -> Path:
    return out / "trials" / robot / controller / axis / f"{value:.6g}"


def _mode(row: dict, summary: dict | None) -> str:
    err = str(row.get("error") or "")
    if row.get("status") == "error":
        kind = err.split(":", 1)[0]
        if summary is None or "Plan" in kind or kind in ("ConfigError", "PlanningError"):
            return "planner refused"   # the scenario's plan (footsteps, centroidal motion) could not be made
        if kind == "QPError" or any(w in err.lower() for w in ("qp", "infeasib", "solver")):
            return "QP infeasible"
        return "error"
    status = (summary or {}).get("controller_status") or {}
    qp_failed = any(("fail" in k or "infeas" in k) and isinstance(v, (int, float)) and v > 0
                    for k, v in status.items())
    if row.get("status") == "fell":
        return "QP infeasible" if qp_failed else "fell"
    return "off the plan"


def _verdict(run_dir: Path, row: dict, tolerance: float) -> tuple[bool, str, str]:
    """(passed, mode, reason) of a finished trial from its cell row and its log."""
    summary_file = run_dir / "summary.json"
    summary = json.loads(summary_file.read_text()) if summary_file.exists() else None
    if row.get("status") != "ok":
        reason = row.get("error") or (summary or {}).get("fall_reason") or row.get("status")
        return False, _mode(row, summary), f"{row.get('status')}: {reason}"
    import pyarrow.parquet as pq

    cols = [f"{c}.{a}" for c in ("com", "com_ref") for a in "xy"]
    try:
        last = pq.read_table(run_dir / "log.parquet", columns=cols)
        last = last.slice(last.num_rows - 1).to_pylist()[0]
    except (OSError, ValueError, KeyError, IndexError):
        return False, "error", "no log"
    err = float(np.hypot(last["com.x"] - last["com_ref.x"], last["com.y"] - last["com_ref.y"]))
    if not np.isfinite(err):
        return True, "", "passed (no CoM reference)"
    if err > tolerance:
        return False, "off the plan", f"final CoM {err:.3f} m from the planned CoM (bound {tolerance} m)"
    return True, "", f"passed (final CoM error {err:.3f} m)"


def _write_trial(study: EnvelopeStudy, controller: str, axis, value: float, d: Path) -> tuple[dict, dict]:
    """The trial's generated scenario written to D/envelope-scenario.yaml; (its mapping, the cell's params)."""
    data, extra = axis.trial(value, study.robot, seed=study.seed)
    d.mkdir(parents=True, exist_ok=True)
    scen = d / "envelope-scenario.yaml"
    scen.write_text(yaml.safe_dump(data, sort_keys=False))
    params = {"scenario": str(scen.resolve()), "controller": controller, "robot": study.robot,
              "seed": study.seed, "engine": study.engine, **_realism_param(study), **extra}
    return data, params


def run_trial(study: EnvelopeStudy, controller: str, axis_name: str, value: float, out: Path) -> dict:
    """One trial (resumed from its verdict.json when done): {value, passed, mode, reason, dir}."""
    from ..study.cell import DONE_FILE, run_cell
    from ..study.sweep import code_version
    from .axes import get_axis

    d = trial_dir(out, study.robot, controller, axis_name, value)
    vfile = d / VERDICT_FILE
    if vfile.exists():
        return json.loads(vfile.read_text())
    _, params = _write_trial(study, controller, get_axis(axis_name), value, d)
    done = d / DONE_FILE
    # a run finished but not judged (killed in between): judged from its row and log, not run again
    row = json.loads(done.read_text()) if done.exists() else run_cell(params, str(d.resolve()), code_version(),
                                                                       d.name)
    passed, mode, reason = _verdict(d / "run", row, study.tolerance)
    v = {"value": value, "passed": passed, "mode": mode, "reason": reason, "dir": str(d),
         "wall_s": row.get("cell_wall_s")}
    vfile.write_text(json.dumps(v, indent=1))
    return v


def _bisection(easy: float, hard: float, res: float):
    """The search of one (controller, axis) as a generator: yields the values to try, is sent each trial's verdict
    (a dict with "passed", "mode", "reason"), returns (limit, first failure, mode, reason)."""
    top = yield hard
    if top["passed"]:
        return hard, None, "limit reached", f"passed the hardest value tried, {hard:g}"
    bottom = yield easy
    if not bottom["passed"]:
        return None, easy, bottom["mode"], bottom["reason"]
    ok, bad, last_bad = easy, hard, top
    while abs(bad - ok) > res * (1 + 1e-9):
        mid = 0.5 * (ok + bad)
        r = yield mid
        if r["passed"]:
            ok = mid
        else:
            bad, last_bad = mid, r
    return ok, bad, last_bad["mode"], last_bad["reason"]


def search_axis(study: EnvelopeStudy, controller: str, axis_name: str, out: str) -> dict:
    """The bisection of one (controller, axis) (see the module docstring); its EnvelopeResult as a dict. An axis
    whose trials share their start (`Axis.branch_at`) simulates it once and branches every trial from it."""
    from .axes import get_axis

    t0 = time.perf_counter()
    out_p = Path(out)
    axis = get_axis(axis_name)
    easy, hard = study.range_of(axis)
    res = study.resolution_of(axis)
    trials = []
    found = None
    if axis.branch_at is not None and hasattr(os, "fork"):
        found = _search_branched(study, controller, axis, _bisection(easy, hard, res), out_p, trials)
    if found is not None:
        limit, fail, mode, reason = found
    else:   # trials from the start (and the fallback of a start that never reached its branch point)
        trials.clear()
        steps = _bisection(easy, hard, res)
        try:
            v = next(steps)
            while True:
                r = run_trial(study, controller, axis_name, round(float(v), 9), out_p)
                trials.append([r["value"], r["passed"], r["mode"], r["reason"], r["dir"]])
                v = steps.send(r)
        except StopIteration as done:
            limit, fail, mode, reason = done.value
    result = EnvelopeResult(controller, axis_name, axis.unit, axis.largest, easy, hard, res, limit, fail, mode,
                            reason, trials, time.perf_counter() - t0)
    return asdict(result)


def _search_branched(study: EnvelopeStudy, controller: str, axis, steps, out: Path, trials: list) -> tuple | None:
    """`search_axis` for an axis whose trials differ only in their pushes after `axis.branch_at`: the start is
    simulated once (prepared as the easy value's trial, its pushes dropped) and each trial is a `Branch` from it
    that writes the same trial directory (scenario, run, cell row, verdict) a trial from the start would. Trials
    already judged are read back, not run again."""
    import shutil

    from ..runner import Branch, BranchPoint, run
    from ..study.cell import DONE_FILE, prepare
    from ..study.sweep import code_version

    result: list = []

    def trial_files(value: float) -> tuple[Path, dict, dict]:
        d = trial_dir(out, study.robot, controller, axis.name, value)
        data, params = _write_trial(study, controller, axis, value, d)
        return d, params, data

    def plan():
        from ..scene import parse_push
        from ..config import Section

        try:
            v = round(float(next(steps)), 9)
            while True:
                d, params, data = trial_files(v)
                vfile = d / VERDICT_FILE
                if vfile.exists():
                    r = json.loads(vfile.read_text())
                else:
                    pushes = tuple(parse_push(Section(p, str(d / "envelope-scenario.yaml"), f"pushes[{k}]"))
                                   for k, p in enumerate(data.get("pushes") or []))
                    summary = yield Branch(d / "run", pushes)
                    row = {"cell_id": d.name, **{f"param.{k}": x for k, x in params.items()},
                           "code_version": code_version(), "branched_at": axis.branch_at}
                    reason = str(summary.get("fall_reason") or "")
                    if "error" in summary or reason.startswith("error:"):
                        row.update(status="error", error=summary.get("error") or reason[len("error: "):])
                    else:
                        row.update(status="fell" if summary.get("fell") else "ok", error=None)
                    (d / DONE_FILE).write_text(json.dumps(row, indent=1, default=str))
                    passed, mode, why = _verdict(d / "run", row, study.tolerance)
                    r = {"value": v, "passed": passed, "mode": mode, "reason": why, "dir": str(d), "wall_s": None}
                    vfile.write_text(json.dumps(r, indent=1))
                trials.append([r["value"], r["passed"], r["mode"], r["reason"], r["dir"]])
                v = round(float(steps.send(r)), 9)
        except StopIteration as done:
            result.append(done.value)

    # a search whose every trial is judged already (resumed) needs no start: read it back
    easy, hard = study.range_of(axis)
    cached = _bisection(easy, hard, study.resolution_of(axis))
    seen = []
    try:
        v = round(float(next(cached)), 9)
        while (vfile := trial_dir(out, study.robot, controller, axis.name, v) / VERDICT_FILE).exists():
            r = json.loads(vfile.read_text())
            seen.append([r["value"], r["passed"], r["mode"], r["reason"], r["dir"]])
            v = round(float(cached.send(r)), 9)
    except StopIteration as done:
        trials.extend(seen)
        return done.value
    approach = out / "trials" / study.robot / controller / axis.name / "approach"
    _, params = _write_trial(study, controller, axis, easy, approach)
    scen, ctrl, robot, options, mode = prepare(params, approach)
    from dataclasses import replace

    scen.spec = replace(scen.spec, pushes=())
    run(scen, ctrl, robot, mode if not hasattr(ctrl, "step") else None, None, approach / "run", sim_options=options,
        overwrite=True, seed=int(study.seed), engine=study.engine, realism=study.realism,
        branch=BranchPoint(axis.branch_at, plan))
    shutil.rmtree(approach, ignore_errors=True)   # a partial run: the trials are the runs
    # None: the start ended before its branch point (e.g. a fall while standing): the caller runs the trials from
    # the start instead
    return result[0] if result else None


def validate(study: EnvelopeStudy) -> None:
    """Before any trial: every axis known, its range one it can take, its resolution positive, and every
    controller able to run its scenario (the easy value's scenario loaded and the controller started on it for
    one control tick). ConfigError otherwise."""
    from ..controllers.base import available_controllers
    from ..errors import UnknownNameError
    from ..robots import load_robot
    from ..runner import run
    from ..scenarios import load_scenario
    from .axes import get_axis
    import tempfile

    ctrls = available_controllers()
    for c in study.controllers:
        if c not in ctrls:
            raise UnknownNameError("controller", c, ctrls, key="--controllers")
    robot = load_robot(study.robot)   # an unknown robot fails here, before any trial
    if study.realism is not None:     # so does a bad realism preset
        from ..sim.realism import check_realism

        check_realism(study.realism, robot, study.engine)
    axes = [get_axis(a) for a in study.axes]
    for a in axes:
        easy, hard = study.range_of(a)
        a.check_range(easy, hard, study.robot)
        if not study.resolution_of(a) > 0:
            raise ConfigError(f"axis '{a.name}': resolution must be > 0, got {study.resolution_of(a)}",
                              key="--resolution")
    with tempfile.TemporaryDirectory(prefix="wbcbench-envelope-") as tmp:
        for a in axes:
            data, extra = a.trial(study.range_of(a)[0], study.robot)
            scen_file = Path(tmp) / f"{a.name}.yaml"
            scen_file.write_text(yaml.safe_dump(data, sort_keys=False))
            for c in study.controllers:
                try:
                    from ..study.cell import prepare

                    scen, ctrl, rob, options, mode = prepare({"scenario": str(scen_file), "controller": c,
                                                              "robot": study.robot, "duration": 0.002, **extra},
                                                             Path(tmp) / f"{a.name}-{c}")
                    run(scen, ctrl, rob, mode if not hasattr(ctrl, "step") else None, None,
                        Path(tmp) / f"{a.name}-{c}" / "run", sim_options=options, overwrite=True,
                        engine=study.engine, realism=study.realism)
                except ConfigError as exc:
                    raise ConfigError(f"controller '{c}' cannot run axis '{a.name}' (scenario {a.scenario}): "
                                      f"{exc}", key="--controllers") from None


def _realism_param(study: EnvelopeStudy) -> dict:
    """The trials' `realism` parameter, absent for the ideal robot (so the settings of earlier studies still
    match)."""
    return {"realism": str(study.realism)} if study.realism is not None else {}


def run_envelope(study: EnvelopeStudy, out: str | Path, executor=None, progress=None) -> list[dict]:
    """Every (controller, axis) search of the study on `executor` (wbcbench.study.execute; default: this process);
    writes envelope.json into `out` and returns the results in (controller, axis) order."""
    from ..study.execute import Executor

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    validate(study)
    settings = {"tolerance": study.tolerance, "seed": study.seed, "engine": study.engine, **_realism_param(study)}
    sfile = out / "settings.json"
    if sfile.exists() and json.loads(sfile.read_text()) != settings:
        raise ConfigError(f"{out} holds trials judged with other settings ({sfile.read_text().strip()}); "
                          "choose another --out", key="--out")
    sfile.write_text(json.dumps(settings))
    jobs = [{"study": study, "controller": c, "axis_name": a, "out": str(out.resolve())}
            for c in study.controllers for a in study.axes]
    done: dict[int, dict] = {}
    executor = executor or Executor()
    for i, r in executor.map_unordered(search_axis, jobs):
        done[i] = r
        if progress:
            progress(len(done), len(jobs), r)
    results = [done[i] for i in range(len(jobs))]
    (out / "envelope.json").write_text(json.dumps({"study": asdict(study), "results": results}, indent=1,
                                                  default=str))
    return results
