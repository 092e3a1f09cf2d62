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


def _trial(study: PushStudy, cell: PushCell, impulse: float, out: Path) -> tuple[bool, str]:
    """One run with one push; (survived, reason)."""
    from ..robots import load_robot
    from ..runner import run
    from ..scenarios import load_scenario
    from ..sim.push import Push

    robot = load_robot(study.robot)
    scen = load_scenario(study.scenario, robot)
    force = impulse / study.push_duration
    a = math.radians(cell.direction_deg)
    push = Push(body="base", force=(force * math.cos(a), force * math.sin(a), 0.0), start=cell.push_time,
                duration=study.push_duration)
    end = cell.push_time + study.push_duration + study.settle
    scen.spec = replace(scen.spec, pushes=(push,), duration=end)
    if study.step_adjustment:
        enable = getattr(scen, "enable_step_adjustment", None)
        if enable is None:
            raise ConfigError(f"scenario '{study.scenario}' (kind {scen.kind}) has no step adjustment",
                              key="--step-adjustment")
        enable()
    res = run(scen, cell.controller, robot=robot, out=out, sensors=study.sensors, seed=cell.seed,
              predict_falls=True, overwrite=True)
    s = res.summary
    if s["fell"]:
        ttf = s["fall_prediction"]["time_to_fall_s"]
        return False, f"fell: {s['fall_reason']}" + (f" (predicted {ttf:.2f} s before)" if ttf is not None else "")
    log = res.log
    com = np.array([log[f"com.{a}"][-1] for a in "xyz"])
    ref = np.array([log[f"com_ref.{a}"][-1] for a in "xyz"])
    dist = float(np.linalg.norm((com - ref)[:2])) if np.isfinite(ref).all() else 0.0
    if dist > study.tolerance:
        return False, f"off the plan: CoM {dist:.3f} m from the planned CoM"
    return True, "survived"


def _bisect(study: PushStudy, cell: PushCell, out_dir: Path) -> PushResult:
    name = f"{cell.controller}-{cell.phase}-{int(cell.direction_deg):03d}deg-s{cell.seed}"
    trials = []

    def attempt(impulse: float) -> bool:
        ok, why = _trial(study, cell, impulse, out_dir / "runs" / f"{name}-{impulse:.2f}Ns")
        trials.append((round(impulse, 4), ok, why))
        return ok

    if study.probe_max and attempt(study.max_impulse):
        return PushResult(cell, study.max_impulse, None, tuple(trials))
    lo, hi = 0.0, study.max_impulse
    for _ in range(study.iterations):
        mid = 0.5 * (lo + hi)
        if attempt(mid):
            lo = mid
        else:
            hi = mid
    if not study.probe_max and hi == study.max_impulse:
        return PushResult(cell, lo, None, tuple(trials))  # never failed below the top: at least `lo`
    return PushResult(cell, lo, hi, tuple(trials))


def _bisect_job(args) -> PushResult:
    return _bisect(*args)


def run_study(study: PushStudy, out_dir: str | Path, jobs: int = 1, progress=None) -> list[PushResult]:
    """Every cell of the study, bisected in `jobs` processes; results in the order of the cells."""
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
    args = [(study, cell, out) for cell in cells]
    results: list[PushResult] = []
    if jobs <= 1:
        for a in args:
            results.append(_bisect_job(a))
            if progress:
                progress(len(results), len(cells))
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for r in pool.map(_bisect_job, args):
                results.append(r)
                if progress:
                    progress(len(results), len(cells))
    (out / "push_results.json").write_text(json.dumps(
        {"study": asdict(study), "phase_times_s": times,
         "results": [{**asdict(r.cell), "survived_impulse_Ns": r.survived_impulse,
                      "failed_impulse_Ns": r.failed_impulse, "trials": [list(t) for t in r.trials]}
                     for r in results]}, indent=2))
    return results


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
             f"its left. Sensors: {study.sensors or 'ideal'}; seeds: {study.seeds}; step adjustment: "
             f"{'on' if study.step_adjustment else 'off'}.", ""]
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
