"""Push-recovery protocol: the largest impulse a controller survives, per push direction and gait phase.

For each (controller, direction, phase, seed) cell, a horizontal force of fixed duration is applied to the base
at the phase's time, and the force is bisected between a push that is survived and one that is not. A push is
survived when the robot does not fall for `settle` seconds after it and its CoM ends within `tolerance` of the
planned CoM (the scenario's reference), i.e. it is back on its plan. The result is the largest survived impulse
[N s] = force x duration, with the bracket it lies in.

Directions are angles in the world x-y plane (the robot starts facing +x): 0 deg pushes forward, 90 deg to the
robot's left. Phases: `ds` (double support; for a standing scenario, 1 s after the start), and for walking
scenarios `ss-early`, `ss-mid`, `ss-late` (10 %, 50 %, 90 % into a single-support phase of the steady gait: the
second one that starts after `after` seconds, or the first if there is no second), with `ds` the middle of the
double support just before it.
"""

from __future__ import annotations

import json
import math
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import ConfigError

__all__ = ["PushCell", "PushResult", "PushStudy", "phase_times", "run_study", "write_report"]

PHASES = ("ds", "ss-early", "ss-mid", "ss-late")


@dataclass(frozen=True)
class PushStudy:
    """What to measure. `push_duration` [s]; `max_impulse` [N s] the upper end of the bisection; `iterations`
    bisection steps after the first trial at `max_impulse` (resolution max_impulse / 2^iterations)."""

    scenario: str
    controllers: tuple[str, ...]
    directions: int = 8
    phases: tuple[str, ...] = ("ds",)
    seeds: int = 1
    push_duration: float = 0.1
    max_impulse: float = 60.0
    iterations: int = 5
    settle: float = 3.0
    tolerance: float = 0.10
    after: float = 2.0
    robot: str = "talos"
    sensors: str | None = None
    probe_max: bool = True
    """First try `max_impulse` itself (to report '>= max'); off, the bisection starts at half of it."""
    step_adjustment: bool = False
    """Switch the walk's DCM-based step adjustment on (wbcbench.planning.step_adjustment, default settings)."""
    engine: str = "mujoco"
    """The physics engine of every trial (`wbcbench.sim.engines`)."""
    realism: str | None = None
    """The realism preset of every trial (`wbcbench.sim.realism`: a name or a YAML file), None: the ideal robot.
    Its sensor profile applies unless `sensors` names one."""


@dataclass(frozen=True)
class PushCell:
    controller: str
    direction_deg: float
    phase: str
    seed: int
    push_time: float


@dataclass(frozen=True)
class PushResult:
    """A cell's outcome: the largest survived impulse [N s] (`survived_impulse`), the smallest failed one
    (`failed_impulse`, None when even `max_impulse` was survived), the trials made (impulse, survived, reason)."""

    cell: PushCell
    survived_impulse: float
    failed_impulse: float | None
    trials: tuple


def phase_times(scenario: str, robot: str = "talos", after: float = 2.0) -> dict[str, float]:
    """The push time [s] of each phase for a scenario (see the module docstring)."""
    from ..robots import load_robot
    from ..scenarios import load_scenario

    rob = load_robot(robot)
    scen = load_scenario(scenario, rob)
    import pinocchio as pin

    q0 = rob.q0.copy()
    scen.setup(q0, pin.centerOfMass(rob.model, rob.model.createData(), q0).copy())
    duration = scen.spec.duration if scen.spec.duration > 0 else scen.planned_duration
    dt = scen.spec.control_dt
    t = np.arange(0.0, duration, dt)
    n_contacts = np.array([len(scen.references(float(x)).contacts) for x in t])
    single = n_contacts == 1
    if not single.any():
        return {"ds": min(1.0, 0.25 * duration)}
    start = np.flatnonzero(single[1:] & ~single[:-1] & (t[1:] >= after)) + 1
    if start.size == 0:
        raise ConfigError(f"scenario '{scenario}' has no single-support phase after {after} s", key="--phases")
    k0 = int(start[1] if start.size > 1 else start[0])
    end = k0 + int(np.argmax(~single[k0:])) if (~single[k0:]).any() else len(t)
    ds_start = k0 - int(np.argmax(single[:k0][::-1])) if single[:k0].any() else 0
    T0, T1 = t[k0], t[end - 1]
    return {"ds": float(0.5 * (t[ds_start] + T0)), "ss-early": float(T0 + 0.1 * (T1 - T0)),
            "ss-mid": float(T0 + 0.5 * (T1 - T0)), "ss-late": float(T0 + 0.9 * (T1 - T0))}


def _trial_scenario(study: PushStudy, robot, push_time: float):
    """The scenario of a trial without its push: it ends `settle` s after the push, step adjustment as asked."""
    from ..scenarios import load_scenario

    scen = load_scenario(study.scenario, robot)
    end = push_time + study.push_duration + study.settle
    scen.spec = replace(scen.spec, pushes=(), duration=end)
    if study.step_adjustment:
        enable = getattr(scen, "enable_step_adjustment", None)
        if enable is None:
            raise ConfigError(f"scenario '{study.scenario}' (kind {scen.kind}) has no step adjustment",
                              key="--step-adjustment")
        enable()
    return scen


def _push(study: PushStudy, cell: PushCell, impulse: float):
    from ..sim.push import Push

    force = impulse / study.push_duration
    a = math.radians(cell.direction_deg)
    return Push(body="base", force=(force * math.cos(a), force * math.sin(a), 0.0), start=cell.push_time,
                duration=study.push_duration)


def _verdict(study: PushStudy, summary: dict, com_end: np.ndarray, ref_end: np.ndarray) -> tuple[bool, str]:
    """(survived, reason) of a trial from its summary and its last CoM and CoM reference."""
    if "error" in summary and "fell" not in summary:
        return False, f"error: {summary['error']}"
    if summary["fell"]:
        ttf = (summary.get("fall_prediction") or {}).get("time_to_fall_s")
        return False, f"fell: {summary['fall_reason']}" + (f" (predicted {ttf:.2f} s before)" if ttf is not None else "")
    dist = float(np.linalg.norm((com_end - ref_end)[:2])) if np.isfinite(ref_end).all() else 0.0
    if dist > study.tolerance:
        return False, f"off the plan: CoM {dist:.3f} m from the planned CoM"
    return True, "survived"


def _trial(study: PushStudy, cell: PushCell, impulse: float, out: Path) -> tuple[bool, str]:
    """One run with one push from the start; (survived, reason)."""
    from ..robots import load_robot
    from ..runner import run

    robot = load_robot(study.robot)
    scen = _trial_scenario(study, robot, cell.push_time)
    scen.spec = replace(scen.spec, pushes=(_push(study, cell, impulse),))
    res = run(scen, cell.controller, robot=robot, out=out, sensors=study.sensors, seed=cell.seed,
              predict_falls=True, overwrite=True, engine=study.engine, realism=study.realism)
    log = res.log
    return _verdict(study, res.summary, np.array([log[f"com.{a}"][-1] for a in "xyz"]),
                    np.array([log[f"com_ref.{a}"][-1] for a in "xyz"]))


def _bisection(study: PushStudy, cell: PushCell):
    """The bisection of one cell as a generator: yields the impulses to try [N s], is sent each trial's
    (survived, reason), returns the `PushResult`."""
    trials = []

    def record(impulse: float, outcome: tuple[bool, str]) -> bool:
        trials.append((round(impulse, 4), outcome[0], outcome[1]))
        return outcome[0]

    if study.probe_max and record(study.max_impulse, (yield study.max_impulse)):
        return PushResult(cell, study.max_impulse, None, tuple(trials))
    lo, hi = 0.0, study.max_impulse
    for _ in range(study.iterations):
        mid = 0.5 * (lo + hi)
        if record(mid, (yield mid)):
            lo = mid
        else:
            hi = mid
    if not study.probe_max and hi == study.max_impulse:
        return PushResult(cell, lo, None, tuple(trials))  # never failed below the top: at least `lo`
    return PushResult(cell, lo, hi, tuple(trials))


def _trial_name(cell: PushCell, impulse: float) -> str:
    return f"{cell.controller}-{cell.phase}-{int(cell.direction_deg):03d}deg-s{cell.seed}-{impulse:.2f}Ns"


def _bisect(study: PushStudy, cell: PushCell, out_dir: Path) -> PushResult:
    """One cell, each trial a run from the start."""
    steps = _bisection(study, cell)
    try:
        impulse = next(steps)
        while True:
            impulse = steps.send(_trial(study, cell, impulse, out_dir / "runs" / _trial_name(cell, impulse)))
    except StopIteration as done:
        return done.value


def _bisect_group(study: PushStudy, cells: list[PushCell], out_dir: Path) -> list[PushResult]:
    """Cells of one controller, phase and seed (so one push time): the approach to the push is simulated once
    and every trial of every cell continues from it (`wbcbench.runner.BranchPoint`), which gives the runs that
    trials from the start give, without re-simulating the approach each time."""
    import shutil

    import pyarrow.parquet as pq

    from ..robots import load_robot
    from ..runner import Branch, BranchPoint, run

    first = cells[0]
    results: list[PushResult] = []

    def plan():
        for cell in cells:
            steps = _bisection(study, cell)
            try:
                impulse = next(steps)
                while True:
                    out = out_dir / "runs" / _trial_name(cell, impulse)
                    summary = yield Branch(out, (_push(study, cell, impulse),))
                    com_end = ref_end = np.full(3, np.nan)
                    try:
                        table = pq.read_table(out / "log.parquet", columns=[f"{c}.{a}" for c in ("com", "com_ref")
                                                                            for a in "xyz"])
                        last = table.slice(table.num_rows - 1)
                        com_end = np.array([last.column(f"com.{a}")[0].as_py() for a in "xyz"])
                        ref_end = np.array([last.column(f"com_ref.{a}")[0].as_py() for a in "xyz"])
                    except (OSError, ValueError, KeyError):  # no log: the summary says why
                        summary = summary if "error" in summary else {**summary, "error": "no log"}
                    impulse = steps.send(_verdict(study, summary, com_end, ref_end))
            except StopIteration as done:
                results.append(done.value)

    robot = load_robot(study.robot)
    scen = _trial_scenario(study, robot, first.push_time)
    # named by the piece's first cell: a group split over processes simulates its approach once per piece, and two
    # pieces sharing a directory (and overwriting it) corrupted each other's log
    name = f"{first.controller}-{first.phase}-{int(first.direction_deg):03d}deg-s{first.seed}-approach"
    approach = out_dir / "runs" / name
    run(scen, first.controller, robot=robot, out=approach, sensors=study.sensors, seed=first.seed,
        predict_falls=True, overwrite=True, branch=BranchPoint(first.push_time, plan), engine=study.engine,
        realism=study.realism)
    shutil.rmtree(approach, ignore_errors=True)  # a partial run: the trials are the raw runs
    return results


def _group_job(args) -> list[PushResult]:
    study, cells, out = args
    if hasattr(os, "fork"):
        return _bisect_group(study, cells, out)
    return [_bisect(study, cell, out) for cell in cells]


def _split(items: list, k: int) -> list[list]:
    """`items` in `k` consecutive parts of nearly equal length."""
    n = len(items)
    return [items[i * n // k:(i + 1) * n // k] for i in range(k)]


def run_study(study: PushStudy, out_dir: str | Path, jobs: int = 1, progress=None) -> list[PushResult]:
    """Every cell of the study, bisected in `jobs` processes; results in the order of the cells. Cells sharing
    controller, phase and seed run as one group (one approach simulated, see `_bisect_group`)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    times = phase_times(study.scenario, study.robot, study.after)
    unknown = [p for p in study.phases if p not in times]
    if unknown:
        raise ConfigError(f"phase(s) {', '.join(unknown)} not in scenario '{study.scenario}' "
                          f"(it has {', '.join(times)})", key="--phases")
    cells = [PushCell(c, 360.0 * k / study.directions, ph, seed, times[ph])
             for c in study.controllers for ph in study.phases for k in range(study.directions)
             for seed in range(study.seeds)]
    groups: dict[tuple, list[PushCell]] = {}
    for cell in cells:
        groups.setdefault((cell.controller, cell.phase, cell.seed), []).append(cell)
    # fewer groups than twice the processes: split them (each piece simulates its approach) to keep all busy
    pieces = max(1, math.ceil(2 * jobs / len(groups))) if jobs > 1 else 1
    args = [(study, part, out) for group in groups.values() for part in _split(group, min(pieces, len(group)))]
    done: dict[PushCell, PushResult] = {}

    def collect(rs: list[PushResult]) -> None:
        done.update((r.cell, r) for r in rs)
        if progress:
            progress(len(done), len(cells))

    if jobs <= 1:
        for a in args:
            collect(_group_job(a))
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for rs in pool.map(_group_job, args):
                collect(rs)
    results = [done[c] for c in cells]
    (out / "push_results.json").write_text(json.dumps(
        {"study": asdict(study), "phase_times_s": times,
         "results": [{**asdict(r.cell), "survived_impulse_Ns": r.survived_impulse,
                      "failed_impulse_Ns": r.failed_impulse, "trials": [list(t) for t in r.trials]}
                     for r in results]}, indent=2))
    return results


def _robot_text(study: PushStudy) -> str:
    from ..sim.realism import realism_label

    return "ideal" if study.realism is None else f"realism preset {realism_label(study.realism)}"


def _sensors_text(study: PushStudy) -> str:
    """The trials' sensor profile: the study's, else its realism preset's, else ideal."""
    if study.sensors is not None:
        return study.sensors
    if study.realism is not None:
        from ..robots import load_robot
        from ..sim.realism import load_realism

        return load_realism(study.realism, load_robot(study.robot)).sensors or "ideal"
    return "ideal"


def write_report(study: PushStudy, results: list[PushResult], out_dir: str | Path) -> Path:
    """push_report.md (a table per phase: controller x direction, impulse survived, mean over seeds) and
    push_polar.png (one polar plot per phase, a curve per controller)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    dirs = sorted({r.cell.direction_deg for r in results})
    table: dict[tuple[str, str], dict[float, list[float]]] = {}
    for r in results:
        table.setdefault((r.cell.controller, r.cell.phase), {}).setdefault(r.cell.direction_deg, []).append(
            r.survived_impulse)
    lines = [f"# Push recovery: {study.scenario}", "",
             f"Largest impulse survived [N s] (push of {study.push_duration} s on the base, bisected to "
             f"{study.max_impulse / 2 ** study.iterations:.2f} N s; survived = no fall for {study.settle} s and the "
             f"CoM back within {study.tolerance} m of the plan; '>=' when the largest impulse tried, "
             f"{study.max_impulse} N s, was survived). Directions in the world frame, the robot facing 0 deg, 90 deg "
             f"its left. Engine: {study.engine}. Robot: {_robot_text(study)}. Sensors: {_sensors_text(study)}; "
             f"seeds: {study.seeds}; step adjustment: {'on' if study.step_adjustment else 'off'}.", ""]
    for phase in study.phases:
        lines += [f"## Phase {phase}", "",
                  "| controller | " + " | ".join(f"{d:.0f} deg" for d in dirs) + " | min |",
                  "|---|" + "---|" * (len(dirs) + 1)]
        for c in study.controllers:
            vals = [float(np.mean(table[(c, phase)][d])) for d in dirs]
            cells = [(">=" if v >= study.max_impulse else "") + f"{v:.1f}" for v in vals]
            lines.append(f"| {c} | " + " | ".join(cells) + f" | {min(vals):.1f} |")
        lines.append("")
    md = out / "push_report.md"
    md.write_text("\n".join(lines))
    fig, axes = plt.subplots(1, len(study.phases), subplot_kw={"projection": "polar"},
                             figsize=(4.2 * len(study.phases), 4.2), squeeze=False)
    for ax, phase in zip(axes[0], study.phases):
        for c in study.controllers:
            vals = [float(np.mean(table[(c, phase)][d])) for d in dirs]
            ang = np.radians(dirs + [dirs[0]])
            ax.plot(ang, vals + [vals[0]], marker="o", label=c)
        ax.set_title(f"{study.scenario}, {phase} [N s]")
        ax.set_rmax(study.max_impulse)
    axes[0][0].legend(loc="lower left", bbox_to_anchor=(-0.2, -0.25), fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "push_polar.png", dpi=90)
    plt.close(fig)
    return md
