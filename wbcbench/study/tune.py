"""`wbcbench tune TUNE.yaml [--trials N] [--jobs N | --ray ADDRESS|auto] [--out DIR]`: Optuna over task-set gains.

```yaml
base: {scenario: walk-20cm-quick, controller: ik, robot: talos}   # any sweep parameters, fixed
params:                                                          # sweep key paths with ranges
  taskset.tasks.com_xy.kp: {min: 20, max: 500, log: true}
  taskset.stabilizer.kp_dcm: {min: 2, max: 30, log: true}
objective:                                                       # minimised: sum of weight * metric
  metrics.zmp_error_m.x.mean: 1.0
  metrics.zmp_error_m.y.mean: 1.0
constraints:                                                     # infeasible trials are pruned
  no_fall: true
  max: {metrics.feet_error_m.peak: 0.05}                         # optional metric bounds
seed: 0
```

Every trial is a sweep cell (trials/trial-NNNN/, its overridden task set in taskset.yaml) run on the same executor
as sweeps (in process, process pool or Ray: trials are asked in batches of the executor's workers). A trial that
falls ends at the fall (the run stops there) and is recorded as pruned, as is one that breaks a constraint or
crashes. The study lives in study.db (SQLite): running the command again continues it up to --trials completed
trials. The shipped task set is run once (baseline/) with the same objective. Outputs: best-taskset.yaml,
report.md (baseline vs best, the optimisation history table and plot history.png).
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

from ..config import load_yaml
from ..errors import ConfigError
from .cell import DONE_FILE, run_cell
from .design import _check_name, _parse_range
from .execute import Executor
from .sweep import code_version


def load_tune(path: str | Path) -> dict:
    file = str(path)
    data = load_yaml(path)
    unknown = set(data) - {"base", "params", "objective", "constraints", "seed", "name", "description"}
    if unknown:
        k = sorted(unknown)[0]
        raise ConfigError(f"unknown key '{k}'; allowed: base, params, objective, constraints, seed", file=file, key=k)
    base = data.get("base") or {}
    if not isinstance(base, dict):
        raise ConfigError("must be a mapping", file=file, key="base")
    for k in base:
        _check_name(k, file, f"base.{k}")
    for need in ("scenario", "controller"):
        if need not in base:
            raise ConfigError(f"'{need}' must be given", file=file, key=f"base.{need}")
    params = data.get("params") or {}
    if not isinstance(params, dict) or not params:
        raise ConfigError("must map at least one key path to {min, max[, log, int]}", file=file, key="params")
    ranges = {}
    for k, spec in params.items():
        _check_name(k, file, f"params.{k}")
        ranges[k] = _parse_range(spec, file, f"params.{k}")
    obj = data.get("objective") or {}
    if not isinstance(obj, dict) or not obj:
        raise ConfigError("must map at least one summary metric (e.g. metrics.zmp_error_m.x.mean) to a weight",
                          file=file, key="objective")
    for k, w in obj.items():
        if not isinstance(w, (int, float)) or isinstance(w, bool):
            raise ConfigError(f"weight must be a number, got {w!r}", file=file, key=f"objective.{k}")
    cons = data.get("constraints") or {}
    if not isinstance(cons, dict) or set(cons) - {"no_fall", "max"}:
        raise ConfigError("allowed keys: no_fall, max", file=file, key="constraints")
    seed = data.get("seed", 0)
    if not isinstance(seed, int):
        raise ConfigError(f"must be an integer, got {seed!r}", file=file, key="seed")
    here = Path(file).resolve().parent
    for k in ("taskset", "scenario", "realism"):
        v = base.get(k)
        if isinstance(v, str) and v.endswith((".yaml", ".yml")) and not Path(v).is_absolute():
            base[k] = str(here / v)
    return {"file": file, "base": base, "ranges": ranges, "objective": obj,
            "no_fall": bool(cons.get("no_fall", True)), "max": dict(cons.get("max") or {}), "seed": seed}


def score(row: dict, spec: dict) -> tuple[float | None, str]:
    """(objective, '') for a feasible row, (None, reason) otherwise."""
    if row.get("status") == "error":
        return None, f"error: {row.get('error')}"
    if spec["no_fall"] and row.get("status") == "fell":
        return None, f"fell at {row.get('sim_time_s', float('nan')):.2f} s"
    for k, bound in spec["max"].items():
        v = row.get(k)
        if v is None or v > bound:
            return None, f"{k} = {v} > {bound}"
    total = 0.0
    for k, w in spec["objective"].items():
        v = row.get(k)
        if v is None or not math.isfinite(v):
            return None, f"metric {k} missing in the summary"
        total += w * v
    return total, ""


def tune(tune_file: str | Path, trials: int, out: str | Path | None = None,
         executor: Executor | None = None, on_trial=None) -> dict:
    import optuna

    spec = load_tune(tune_file)
    if trials < 1:
        raise ConfigError(f"--trials must be >= 1, got {trials}", key="--trials")
    out = Path(out) if out is not None else Path("tuning") / Path(tune_file).stem
    from .cell import prepare
    probe = {**spec["base"], **{k: (int(lo) if integer else lo) for k, (lo, hi, log, integer) in spec["ranges"].items()}}
    try:   # an unknown key path or a rejected value fails before any run
        prepare(probe, out / ".validate")
    except ConfigError as exc:
        raise ConfigError(str(exc), file=spec["file"]) from None
    finally:
        shutil.rmtree(out / ".validate", ignore_errors=True)
    out.mkdir(parents=True, exist_ok=True)
    executor = executor or Executor()
    version = code_version()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(study_name=Path(tune_file).stem, storage=f"sqlite:///{(out / 'study.db').resolve()}",
                                load_if_exists=True, direction="minimize",
                                sampler=optuna.samplers.TPESampler(seed=spec["seed"]))
    # the shipped gains, measured the same way
    base_dir = out / "baseline"
    if (base_dir / DONE_FILE).exists():
        base_row = json.loads((base_dir / DONE_FILE).read_text())
    else:
        base_row = next(r for _, r in executor.map_unordered(
            run_cell, [{"params": dict(spec["base"]), "cell_dir": str(base_dir.resolve()), "code_version": version,
                        "cell_id": "baseline"}]))
    base_score, base_why = score(base_row, spec)

    def finished() -> int:
        return sum(t.state in (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
                   for t in study.trials)

    while finished() < trials:
        batch = [study.ask() for _ in range(min(executor.workers, trials - finished()))]
        kwargs = []
        for t in batch:
            p = dict(spec["base"])
            for k, (lo, hi, log, integer) in spec["ranges"].items():
                p[k] = (t.suggest_int(k, int(lo), int(hi), log=log) if integer
                        else t.suggest_float(k, lo, hi, log=log))
            kwargs.append({"params": p, "cell_dir": str((out / "trials" / f"trial-{t.number:04d}").resolve()),
                           "code_version": version, "cell_id": f"trial-{t.number:04d}"})
        for i, row in executor.map_unordered(run_cell, kwargs):
            t = batch[i]
            val, why = score(row, spec)
            t.set_user_attr("status", row.get("status"))
            t.set_user_attr("note", why)
            for k in spec["objective"]:
                if row.get(k) is not None:
                    t.set_user_attr(k, row[k])
            if val is None:
                study.tell(t, state=optuna.trial.TrialState.PRUNED)
            else:
                study.tell(t, val)
            if on_trial is not None:
                on_trial(finished(), trials, val)
    return write_tune_report(study, spec, out, base_row, base_score, base_why)


def _robot_text(base: dict) -> str:
    from ..sim.realism import realism_label

    label = realism_label(base.get("realism"))
    return label if label == "ideal" else f"realism preset {label}"


def write_tune_report(study, spec: dict, out: Path, base_row: dict, base_score, base_why: str) -> dict:
    import optuna
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    complete = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    best = study.best_trial if complete else None
    if best is not None:
        shutil.copy(out / "trials" / f"trial-{best.number:04d}" / "taskset.yaml", out / "best-taskset.yaml")
    obj_keys = list(spec["objective"])
    lines = [f"# Tuning: {Path(spec['file']).name}", "",
             f"Base: {json.dumps(spec['base'])}. Objective (minimised): "
             + " + ".join(f"{w} * `{k}`" for k, w in spec["objective"].items())
             + f". Constraints: no fall = {spec['no_fall']}, bounds = {spec['max'] or 'none'}. "
               f"Sampler TPE, seed {spec['seed']}. Code: {base_row.get('code_version')}. "
               f"Engine: {spec['base'].get('engine') or 'mujoco'}. Robot: {_robot_text(spec['base'])}.", "",
             "| | objective | " + " | ".join(obj_keys) + " | fell |", "|---|---|" + "---|" * len(obj_keys) + "---|"]

    def f(v):
        return "-" if v is None else f"{v:.5g}"
    lines.append(f"| shipped gains | {f(base_score)} | " + " | ".join(f(base_row.get(k)) for k in obj_keys)
                 + f" | {base_row.get('status') == 'fell'} |")
    if best is not None:
        lines.append(f"| best trial #{best.number} | {f(best.value)} | "
                     + " | ".join(f(best.user_attrs.get(k)) for k in obj_keys) + " | False |")
        lines += ["", "Best gains: " + ", ".join(f"`{k}` = {v:.4g}" for k, v in best.params.items()),
                  "(best task set: best-taskset.yaml)."]
    n_pruned = sum(t.state == optuna.trial.TrialState.PRUNED for t in study.trials)
    lines += ["", f"{len(study.trials)} trials: {len(complete)} complete, {n_pruned} pruned (fell, broke a "
                  "constraint or crashed).", "", "## History", "", "![history](history.png)", "",
              "| trial | state | objective | " + " | ".join(spec["ranges"]) + " | note |",
              "|---|---|---|" + "---|" * len(spec["ranges"]) + "---|"]
    for t in study.trials:
        lines.append(f"| {t.number} | {t.state.name.lower()} | {f(t.value)} | "
                     + " | ".join(f(t.params.get(k)) for k in spec["ranges"]) + f" | {t.user_attrs.get('note', '')} |")
    (out / "report.md").write_text("\n".join(lines) + "\n")
    fig, ax = plt.subplots(figsize=(6, 3.5))
    xs = [t.number for t in complete]
    ys = [t.value for t in complete]
    ax.plot(xs, ys, "o", ms=4, label="trial")
    if ys:
        ax.plot(xs, [min(ys[: i + 1]) for i in range(len(ys))], "-", label="best so far")
    if base_score is not None:
        ax.axhline(base_score, color="k", ls="--", lw=1, label="shipped gains")
    ax.set_xlabel("trial")
    ax.set_ylabel("objective")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "history.png", dpi=80)
    plt.close(fig)
    return {"out": out, "best": None if best is None else {"number": best.number, "value": best.value,
                                                           "params": best.params},
            "baseline": base_score, "n_trials": len(study.trials)}
